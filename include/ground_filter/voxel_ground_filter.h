#ifndef GROUND_FILTER_VOXEL_GROUND_FILTER_H
#define GROUND_FILTER_VOXEL_GROUND_FILTER_H

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"

namespace ground_filter {

/// \brief Parameters of the voxel method (Diaz et al., section 2.3.2). One line per field:
///        meaning [unit] (default; paper value when it differs).
struct VoxelGroundFilterParams {
  double voxel_size = 0.10;          ///< voxel edge length [m] (0.10, paper)
  double flatness_threshold = 0.04;  ///< a voxel is flat when max z - min z < this [m] (0.04)
  int min_points_per_voxel = 2;      ///< voxels with fewer points are never flat [points] (2)
  double height_margin = 1.0;        ///< global plane: flat voxels above mean flat height + this are dropped [m] (1.0)
  double seed_window = 0.5;          ///< local planes: seeds within this of the predicted tile plane [m] (0.5)
  double plane_distance = 0.10;      ///< max point-to-plane distance of a ground point [m] (0.10)
  bool std_filter = false;           ///< also require |distance - mean| <= std_multiplier * std [bool] (false; paper: true)
  double std_multiplier = 1.0;       ///< width of the mean +- std band in standard deviations [-] (1.0)
  bool local_planes = true;          ///< one plane per tile instead of one for the scan [bool] (true)
  double tile_size = 8.0;            ///< tile edge for local planes [m] (8.0)
  double max_slope_deg = 30.0;       ///< steeper tile planes are rejected, the neighbour's is kept [deg] (30)
  bool majority_vote = true;         ///< final 26-neighbourhood majority vote per voxel [bool] (true)
  int threads = 1;                   ///< worker threads, 0 = all cores [threads] (1)

  /// \brief Sets one field from text (CLI `--set NAME=VALUE`).
  /// \throws std::invalid_argument for an unknown name or a malformed value.
  void set(const std::string& name, const std::string& value);
  /// \brief Checks every field's range.
  /// \throws std::invalid_argument naming the first bad field, its value and its range.
  void validate() const;
};

/// \brief Voxel-based ground filter: flat voxels, height filter, 26-adjacency region growing,
///        plane fit(s), distance filter and a final 26-neighbourhood majority vote.
class VoxelGroundFilter : public GroundFilter {
 public:
  /// \brief Validates and stores `params`.
  /// \throws std::invalid_argument when params.validate() fails.
  explicit VoxelGroundFilter(const VoxelGroundFilterParams& params = VoxelGroundFilterParams());
  ~VoxelGroundFilter() override;

  void filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
              FilterStats* stats = nullptr) override;
  std::string name() const override { return "voxel"; }

  /// \brief The parameters in use.
  const VoxelGroundFilterParams& params() const { return params_; }

 private:
  struct Impl;
  VoxelGroundFilterParams params_;
  std::unique_ptr<Impl> impl_;  // scratch buffers reused between calls
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_VOXEL_GROUND_FILTER_H
