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
  /// \brief Rewrites `cls->ground` (reads the classification only: all sums come first).
  ///        `threads` > 1 splits the columns into ranges of whole rows.
  void run(const VoxelGrid& g, int threads, WorkerPool* pool, Classifier* cls);

 private:
  struct ColInfo {
    std::int32_t base, ext;    // z prefix range base .. base + ext - 1; ext < 0: scan voxels
    std::uint32_t pool;        // offset of the prefix sums in pre_ (pairs)
    std::uint32_t first, end;  // voxels
  };
  /// Per column, the z range of the voxels whose vote can change (alo_ > ahi_: none).
  void votedRanges(const VoxelGrid& g, const Classifier& cls, int t, int range);
  /// Sums of the voted voxels of the columns of `range`, on thread t.
  void sums(const VoxelGrid& g, const Classifier& cls, int t, int range, bool lazy);
  /// Prefix sums of column c into pre_.
  void buildColumn(const VoxelGrid& g, const Classifier& cls, std::size_t c);

  std::vector<std::size_t> bounds_;                 // column ranges (whole rows)
  std::vector<std::vector<ZRange>> range_rows_;     // per thread
  std::vector<std::vector<std::int32_t>> id_rows_;  // per thread
  std::vector<std::int32_t> alo_, ahi_;
  std::vector<ColInfo> col_info_;    // + one empty sentinel
  std::vector<std::uint32_t> pre_;   // z prefix sums of (ground, all) points
  std::vector<std::uint8_t> built_;  // prefix sums of the column are in pre_
  std::vector<std::uint32_t> sum_g_, sum_n_;
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_VOTE_H
