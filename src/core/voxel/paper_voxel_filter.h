#ifndef GROUND_FILTER_SRC_CORE_VOXEL_PAPER_VOXEL_FILTER_H
#define GROUND_FILTER_SRC_CORE_VOXEL_PAPER_VOXEL_FILTER_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/param_table.h"
#include "ground_filter/voxel_ground_filter.h"

namespace ground_filter {

/// \brief The voxel method's parameters as the paper states them: 0.1 voxels, 0.04 flatness,
///        one global plane, 0.10 distance with the mean +- 1 std band, height margin 1.
VoxelGroundFilterParams paperVoxelParams();

/// \brief Parameters of `voxel_paper`: its own two (table()) and the voxel method's, which
///        start from paperVoxelParams(). set() tries the own rows first, then the voxel
///        method's (an unknown name is reported by the voxel table, as before).
struct PaperVoxelParams : TableParams<PaperVoxelParams> {
  int segment_points = 65536;       ///< points per segment, in input order [points] (65536)
  bool paper_normalisation = true;  ///< logistic z-score mapping per segment [bool] (true)
  VoxelGroundFilterParams voxel = paperVoxelParams();  ///< the voxel filter run on each segment

  /// \brief Sets one field (own row or the voxel method's) from text.
  /// \throws std::invalid_argument for an unknown name or a malformed value.
  void set(const std::string& name, const std::string& value);
  /// \brief The voxel method's checks, then the ranges of the own rows.
  /// \throws std::invalid_argument naming the first bad field, its value and its range.
  void validate() const;
  /// \brief "name=value ..." of the own rows, then of the voxel method's.
  std::string describe() const;
  /// \brief The own rows: segment_points, paper_normalisation.
  static const ParamTable<PaperVoxelParams>& table();
  /// \brief "voxel_paper": the method's name (messages, makeGroundFilter()).
  static const char* method() { return "voxel_paper"; }
};

/// \brief The authors' normalisation (MATLAB `standart.m`): each coordinate v of the valid
///        points of input indices [begin, end) becomes 1 / (1 + exp(-(v - mean) / std)), mean
///        and sample std (n - 1) over those points, per axis; an axis without spread maps to 0.5.
///        Appends the mapped points to `xyz` (packed x y z) and their input indices to `index`;
///        with `normalise` false the points are appended unmapped.
void paperNormaliseSegment(const CloudView& cloud, std::size_t begin, std::size_t end,
                           std::vector<float>* xyz, std::vector<std::size_t>* index,
                           bool normalise = true);

/// \brief Voxel filter on the paper's normalised coordinates (`voxel_paper`): the input is cut
///        into consecutive segments of `segment_points` points in input order (MainVoxel.m:
///        65,536), every segment is mapped by paperNormaliseSegment() and filtered on its own
///        by a VoxelGroundFilter with `params` (default paperVoxelParams(), whose lengths are
///        then in normalised units). With `normalise` false the segments keep their metric
///        coordinates (the same pipeline without the mapping, for comparison). Same output
///        contract as every GroundFilter.
class PaperNormalisedVoxelFilter : public GroundFilter {
 public:
  /// \brief Validates and stores the parameters.
  /// \throws std::invalid_argument when params.validate() fails.
  explicit PaperNormalisedVoxelFilter(const PaperVoxelParams& params = PaperVoxelParams());

  void filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
              FilterStats* stats = nullptr) override;
  std::string name() const override { return "voxel_paper"; }

 private:
  VoxelGroundFilter voxel_;
  std::size_t segment_points_;
  bool normalise_;
  std::vector<float> xyz_;          // normalised points of one segment
  std::vector<std::size_t> index_;  // their input indices
  std::vector<std::uint8_t> segment_labels_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_PAPER_VOXEL_FILTER_H
