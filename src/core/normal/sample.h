#ifndef GROUND_FILTER_SRC_CORE_NORMAL_SAMPLE_H
#define GROUND_FILTER_SRC_CORE_NORMAL_SAMPLE_H

#include <cstddef>
#include <cstdint>
#include <vector>

namespace ground_filter {
namespace normal {

/// \brief Stage 1b ("sample", sample_stride > 1): the points that get a neighbourhood, a normal
///        and a vote are every stride-th point of a segment in column order; every other point
///        is voted when the sampled point before or after it is. Neighbouring points in column
///        order share a 0.1 m column, so their neighbourhoods all but coincide: the sample keeps
///        the area a normal sees (with k / stride neighbours) at 1 / stride of the queries. Holds
///        only scratch memory, reused between scans.
class SampleStage {
 public:
  /// \brief Gathers points 0, stride, 2 stride, ... of the `len` points at `xyz` (x y z packed).
  /// \return the number of sampled points; their xyz is sampledXyz().
  std::size_t gather(const float* xyz, std::size_t len, int stride);
  /// \brief Packed xyz of the sampled points (valid after gather()).
  const float* sampledXyz() const { return xyz_.data(); }
  /// \brief Candidate flags of the sampled points (the neighbourhood stage writes them).
  std::uint8_t* candidates() { return candidate_.data(); }
  /// \brief Votes of the sampled points (the vote stage writes them).
  std::uint8_t* votes() { return voted_.data(); }
  /// \brief Votes of the `len` points of the segment: a sampled point's own, another point's
  ///        the OR of the sampled points before and after it (the last one's alone at the end).
  void spread(std::size_t len, int stride, std::uint8_t* voted) const;

 private:
  std::vector<float> xyz_;
  std::vector<std::uint8_t> candidate_, voted_;
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_SAMPLE_H
