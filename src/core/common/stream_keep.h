// Private to the core: when a measurement of one scan may stand for the next scans of the same
// stream (a sensor's scan lines, what its origin sees).
#ifndef GROUND_FILTER_SRC_CORE_COMMON_STREAM_KEEP_H
#define GROUND_FILTER_SRC_CORE_COMMON_STREAM_KEEP_H

#include <algorithm>
#include <cstddef>

namespace ground_filter {

/// \brief Whether a per-stream measurement is kept for a scan or taken again: taken on the
///        first scan, every `every`-th, and when the point count moves by more than a tenth or
///        the origin moves (another sensor); kept otherwise, as a sensor does not change from
///        scan to scan.
class StreamKeep {
 public:
  explicit StreamKeep(int every) : every_(every) {}

  /// \brief Measure again every `every`-th scan from now on (a measurement that found nothing
  ///        to act on may stand longer).
  void setEvery(int every) { every_ = every; }

  /// \brief true: keep the last measurement for this scan; false: measure it again (this scan
  ///        becomes the one later scans are compared with).
  bool keep(std::size_t points, const float origin[3]) {
    const std::size_t diff = points > points_ ? points - points_ : points_ - points;
    if (age_ >= 0 && age_ + 1 < every_ && 10 * diff <= points_ && origin[0] == origin_[0] &&
        origin[1] == origin_[1] && origin[2] == origin_[2]) {
      ++age_;
      return true;
    }
    points_ = points;
    std::copy(origin, origin + 3, origin_);
    age_ = 0;
    return false;
  }

 private:
  int every_;
  std::size_t points_ = 0;  // points of the scan measured last
  float origin_[3] = {0.f, 0.f, 0.f};
  int age_ = -1;  // scans since; -1: none measured
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_STREAM_KEEP_H
