#ifndef GROUND_FILTER_SRC_CORE_NORMAL_SAMPLE_H
#define GROUND_FILTER_SRC_CORE_NORMAL_SAMPLE_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/scan_lines.h"
#include "normal/order.h"

namespace ground_filter {
namespace normal {

/// \brief Stage 1b ("sample", sample_stride > 1): the points that get a neighbourhood, a normal
///        and a vote are every stride-th point of a segment in column order; every other point
///        is voted when the sampled point before or after it is. Neighbouring points in column
///        order share a 0.1 m column, so their neighbourhoods all but coincide: the sample keeps
///        the area a normal sees (with k / stride neighbours) at 1 / stride of the queries.
///        A column of more than `stride * column_cap` points (a dense TLS station near its
///        tripod) gives at most `column_cap` sampled points, evenly spaced in it: the k nearest
///        sampled neighbours of a point then span centimetres, not the few millimetres (less
///        than the range noise) of every stride-th point (cpu_gpu_common.h: columnSampleCap(),
///        columnSampleStep()). Holds only scratch memory, reused between scans.
class SampleStage {
 public:
  /// \brief Samples the `len` points at `xyz` (x y z packed, column order of `grid`), copying
  ///        them on up to `threads` threads.
  /// \return the number m of sampled points; their xyz is sampledXyz(), their positions
  ///         sampledIndex().
  std::size_t gather(const float* xyz, std::size_t len, int stride, int column_cap,
                     const ColumnGrid& grid, int threads = 1);
  /// \brief Packed xyz of the sampled points (valid after gather()).
  const float* sampledXyz() const { return xyz_.data(); }
  /// \brief m + 1 positions: sampled point j is point sampledIndex()[j] of the segment, the last
  ///        entry is `len`; the points from one sampled point up to the next use its list.
  const std::uint32_t* sampledIndex() const { return index_.data(); }
  /// \brief Candidate flags of the sampled points (the neighbourhood stage writes them).
  std::uint8_t* candidates() { return candidate_.data(); }
  /// \brief Votes of the sampled points (the vote stage writes them).
  std::uint8_t* votes() { return voted_.data(); }
  /// \brief Votes of the `len` points of the segment: a sampled point's own, another point's
  ///        the OR of the sampled points before and after it (the last one's alone at the end);
  ///        sampledIndex()[m] of them.
  void spread(std::uint8_t* voted) const;

 private:
  std::vector<float> xyz_;
  std::vector<std::uint32_t> index_;
  std::vector<std::uint8_t> candidate_, voted_;
};

/// \brief Stage 1a: `stride`, doubled (at most kMaxSampleStride) while lines.ratio() / stride
///        exceeds `max_ratio`: the sampled points of a line then lie at least 1 / max_ratio of
///        the line spacing apart, and a point's K nearest samples reach the next line. `stride`
///        itself when max_ratio is 0 or no lines were found (common/scan_lines.h).
int strideForScanLines(const ScanLines& lines, double max_ratio, int stride);

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_SAMPLE_H
