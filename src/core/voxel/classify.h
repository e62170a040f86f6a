// Private to the voxel filter: per-point distance test against the ground model.
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_CLASSIFY_H
#define GROUND_FILTER_SRC_CORE_VOXEL_CLASSIFY_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/voxel_ground_filter_params.h"
#include "voxel/ground_model.h"
#include "voxel/segments.h"
#include "voxel/voxel_grid.h"
#include "voxel/worker_pool.h"

namespace ground_filter {
namespace voxel {

/// \brief z range of a column's voxels holding ground (g) and non-ground (n) points.
struct ZRange {
  std::int32_t glo, ghi, nlo, nhi;
};
constexpr ZRange kEmptyRange{kNoLo, kNoHi, kNoLo, kNoHi};

/// \brief What the per-point test needs of a cell: its plane's slope and cosine (float) and the
///        accepted band of signed distances.
struct CellCoef {
  float a, b, cos, lo, hi;
};

/// \brief What Classifier writes (the vote and the vegetation rule rewrite `ground`).
struct ClassifyResult {
  /// \brief Label per point in key order (1 ground).
  std::vector<std::uint8_t> ground;
  /// \brief Ground points per voxel.
  std::vector<std::uint32_t> voxel_ground;
  /// \brief Per column: z range of the voxels with ground / non-ground points (+ one empty
  ///        sentinel column).
  std::vector<ZRange> col_range;
  /// \brief Per column: 1 when it holds ground points, | 2 when it holds non-ground points
  ///        (+ 0 for the sentinel).
  std::vector<std::uint8_t> col_mask;
  /// \brief Per voxel: height of its cell's plane at the voxel's centroid.
  std::vector<float> plane_height;
};

/// \brief Step 7: ground = within plane_distance of the cell plane (and, with std_filter, inside
///        the cell's mean +- k std band).
class Classifier {
 public:
  /// \brief Labels every point of `g` (key order) into `out`. `seg.best` is the largest
  ///        segment (global mode std band); `threads` > 1 splits the columns.
  void run(const VoxelGroundFilterParams& p, const VoxelGrid& g, const CellGrid& cells,
           const GroundModelResult& model, const SegmentResult& seg, int threads, WorkerPool* pool,
           ClassifyResult* out);

 private:
  void bandStats(const VoxelGroundFilterParams& p, const VoxelGrid& g, std::size_t cells,
                 const GroundModelResult& model, const SegmentResult& seg);
  std::vector<double> mu_, sigma_;  // std band per cell
  std::vector<CellCoef> coef_;
  std::vector<std::uint64_t> count_;
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_CLASSIFY_H
