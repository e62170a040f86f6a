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
///        meaning [unit] (default; paper value when it differs). docs/voxel_method.md says
///        what each step does with them and gives the measurements behind every default that
///        differs from the paper (paper: plane_distance 0.10, std_filter on, one global plane).
struct VoxelGroundFilterParams {
  double voxel_size = 0.10;          ///< voxel edge length [m] (0.10, paper)
  double flatness_threshold = 0.04;  ///< flat voxel: max z - min z below this [m] (0.04)
  int min_points_per_voxel = 2;      ///< voxels with fewer points are never flat [points] (2)
  double height_margin = 1.0;        ///< global: cut over mean flat z; local: seed depth [m] (1.0)
  double seed_window = 0.2;          ///< local: seeds at most this above the prediction [m] (0.2)
  double plane_distance = 0.15;      ///< max |distance| of a ground point to its plane [m] (0.15)
  bool std_filter = false;           ///< mean +- k std band test too [bool] (false; paper on)
  double std_multiplier = 1.0;       ///< k of that band, in standard deviations [1] (1.0)
  bool local_planes = true;          ///< grown cell planes, not one plane [bool] (true; paper off)
  double tile_size = 1.0;            ///< cell edge of the local model, >= 2 voxel_size [m] (1.0)
  double max_slope_deg = 30.0;       ///< steeper cell / global planes are rejected [deg] (30)
  bool majority_vote = true;         ///< final 26-neighbourhood vote per voxel [bool] (true)
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
///
/// With `local_planes` (default) the single plane of the paper becomes a ground model of
/// `tile_size` cells grown outwards from the largest flat segment, each cell fitted to the
/// lowest voxels of its columns near the prediction of its neighbours (docs/voxel_method.md).
///
/// With `threads` > 1, scans of at least 150 k valid points split the key computation, sort,
/// classification and vote over that many threads; the labels are the same for any thread count.
/// Scratch buffers (and worker threads) are kept: a repeated scan of the same size allocates
/// nothing when `labels` and `stats` are reused.
class VoxelGroundFilter : public GroundFilter {
 public:
  /// \brief Validates and stores `params`.
  /// \throws std::invalid_argument when params.validate() fails.
  explicit VoxelGroundFilter(const VoxelGroundFilterParams& params = VoxelGroundFilterParams());
  ~VoxelGroundFilter() override;

  /// \brief Labels every point (NaN/Inf points are non-ground and never used). Stage timings
  ///        go to `stats->stage_ms` only when `stats` is given.
  /// \throws std::runtime_error when the cloud spans more than 2^21 voxels along an axis.
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
