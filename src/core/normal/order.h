#ifndef GROUND_FILTER_SRC_CORE_NORMAL_ORDER_H
#define GROUND_FILTER_SRC_CORE_NORMAL_ORDER_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/radix_sort.h"
#include "ground_filter/cloud_view.h"

namespace ground_filter {
namespace normal {

/// \brief x/y bounding box of the valid points.
struct Extent {
  double min_x = 0.0, min_y = 0.0, max_x = 0.0, max_y = 0.0;
  /// \brief Larger side of the box [m].
  double size() const { return std::max(max_x - min_x, max_y - min_y); }
};

/// \brief The output of OrderStage: the valid points of one scan in grid-column order.
struct OrderedPoints {
  std::vector<float> xyz;                                     ///< packed x y z, column order
  std::vector<std::uint32_t> source;                          ///< input index of each point
  std::vector<std::pair<std::size_t, std::size_t>> segments;  ///< [begin, end) in column order
  Extent extent;                                              ///< bounding box of the points
  double cell = 0.0;  ///< the grid's cell [m]: cell_size, coarser for very wide clouds
};

/// \brief The x/y grid of the column order: a point's column is
///        (cellIndex(x, min_x, inv_cell), cellIndex(y, min_y, inv_cell)).
struct ColumnGrid {
  double min_x = 0.0, min_y = 0.0, inv_cell = 1.0;
};

/// \brief The grid of `points`' column order (SampleStage caps a dense column's sample).
inline ColumnGrid columnGrid(const OrderedPoints& points) {
  return ColumnGrid{points.extent.min_x, points.extent.min_y, 1.0 / points.cell};
}

/// \brief Stage 1 ("sort"): the finite points compacted and ordered by x/y grid column (Morton
///        order of the cells), so neighbouring points are close in memory, then cut into
///        segments of whole columns. Holds only scratch memory, reused between scans.
class OrderStage {
 public:
  /// \brief Orders the valid points of `cloud` on a `cell_size` grid into `out`; with
  ///        `use_segments`, cuts them into segments of at most `segment_points` (else one
  ///        segment); `threads` for the per-point loops.
  /// \return the number of valid points.
  std::size_t run(const CloudView& cloud, double cell_size, bool use_segments, int segment_points,
                  int threads, OrderedPoints* out);
  /// \brief The column key (columnKey()) of each point of the last run()'s `out`, in its order.
  const std::uint64_t* columnKeys() const { return sort_scratch_.keys.data(); }
  /// \brief `out` from a column order made elsewhere (the GPU's,
  ///        NormalFilterExecutor::lastColumnOrder()): `out->source` given, the points of `cloud`
  ///        there gathered into `out->xyz`, their extent and cell as run() gives them, one
  ///        segment. (columnKeys() do not belong to it.)
  static void fromOrder(const CloudView& cloud, double cell_size, OrderedPoints* out);

 private:
  std::vector<float> raw_xyz_;
  std::vector<std::uint32_t> raw_source_;
  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> order_;
  RadixSortScratch sort_scratch_;
  std::vector<std::size_t> block_count_;  // compaction: valid points before each block
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_ORDER_H
