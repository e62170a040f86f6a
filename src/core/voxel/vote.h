// Private to the voxel filter: final 26-neighbourhood majority vote.
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_VOTE_H
#define GROUND_FILTER_SRC_CORE_VOXEL_VOTE_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "voxel/classify.h"
#include "voxel/voxel_grid.h"
#include "voxel/worker_pool.h"

namespace ground_filter {
namespace voxel {

/// \brief Step 8: every voxel takes the point-weighted majority label of its 3 x 3 x 3
///        neighbourhood (itself included); ties keep the per-point labels.
class Voter {
 public:
  /// \brief Rewrites `cls->ground` (the sums read the per-voxel ground counts of the
  ///        classification only, so relabelling as it goes is exact). `threads` > 1 splits the
  ///        columns into ranges of whole rows.
  void run(const VoxelGrid& g, int threads, WorkerPool* pool, ClassifyResult* cls);

 private:
  /// Votes, on thread t, the voxels of the columns of `range` (whole rows) whose neighbourhood
  /// holds both labels.
  void vote(const VoxelGrid& g, int t, int range, ClassifyResult* cls);

  std::vector<std::size_t> bounds_;                 // column ranges (whole rows)
  std::vector<std::vector<std::int64_t>> id_rows_;  // per thread: column id << 2 | label mask
  std::vector<std::vector<std::uint64_t>> acc_;     // per thread: ground << 32 | points per z
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_VOTE_H
