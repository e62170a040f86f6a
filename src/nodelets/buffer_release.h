#ifndef GROUND_FILTER_SRC_NODELETS_BUFFER_RELEASE_H
#define GROUND_FILTER_SRC_NODELETS_BUFFER_RELEASE_H

#include <algorithm>
#include <cstddef>

namespace ground_filter {

/// \brief When to drop a filter's scratch buffers after a rare huge cloud.
///
/// A filter keeps its buffers between clouds (no allocation per cloud), sized by the largest cloud
/// it has seen. One 20 M-point cloud on a 240 k-point stream would otherwise hold gigabytes until
/// the nodelet restarts. The rule: once the largest cloud since the last release had at least
/// `min_points` and `calm_clouds` clouds in a row have each been at most 1/`ratio` of it, the
/// nodelet rebuilds its filter (buffers freed, then sized by the clouds that follow).
class BufferReleasePolicy {
 public:
  /// \brief `min_points`: smaller peaks never trigger (their buffers are cheap); `ratio`: how much
  ///        smaller the clouds after the peak must be; `calm_clouds`: for how many clouds in a row.
  explicit BufferReleasePolicy(std::size_t min_points = std::size_t{1} << 20, double ratio = 4.0,
                               int calm_clouds = 10)
      : min_points_(min_points), ratio_(ratio), calm_clouds_(calm_clouds) {}

  /// \brief Records a processed cloud of `points`; true when the buffers should go now (the
  ///        policy then starts afresh).
  bool afterCloud(std::size_t points) {
    peak_ = std::max(peak_, points);
    if (peak_ < min_points_ || static_cast<double>(points) * ratio_ > static_cast<double>(peak_)) {
      calm_ = 0;
      return false;
    }
    if (++calm_ < calm_clouds_) return false;
    peak_ = 0;
    calm_ = 0;
    return true;
  }

  /// \brief Forgets the peak (the filter was rebuilt for another reason).
  void reset() {
    peak_ = 0;
    calm_ = 0;
  }

 private:
  std::size_t min_points_;
  double ratio_;
  int calm_clouds_;
  std::size_t peak_ = 0;  // largest cloud since the last release [points]
  int calm_ = 0;          // clouds in a row at most peak_ / ratio_
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_BUFFER_RELEASE_H
