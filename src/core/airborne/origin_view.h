// Private to the core: whether the origin can be the one viewpoint a cloud was seen
// from, or the cloud holds much the origin cannot see (merged stations or sweeps).
#ifndef GROUND_FILTER_SRC_CORE_AIRBORNE_ORIGIN_VIEW_H
#define GROUND_FILTER_SRC_CORE_AIRBORNE_ORIGIN_VIEW_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/stream_keep.h"
#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief Measures the share of a cloud's points that lie behind nearer points as seen from the
///        origin, keeping its buffers from call to call.
///
/// A sensor returns the first surface along each ray: seen from a single scan's sensor, no
/// point lies behind another (only at object edges, mixed pixels and second echoes). A cloud
/// merged from several stations or sweeps holds the far side of hills, walls and parked cars,
/// which the origin cannot see. The normal method's rule that no ground plane passes above the
/// sensor holds only for the first; for the second it refuses the ground of any terrain higher
/// than the origin (docs/normal_method.md, "Ceilings").
class OriginView {
 public:
  /// \brief Points read (evenly spread over the cloud) per measurement.
  static constexpr std::size_t kMaxRead = 16384;
  /// \brief Direction bins: this much azimuth [deg] ...
  static constexpr double kAzimuthBin = 1.0;
  /// \brief ... by this much elevation at the horizon [deg] (twice as much at 45 deg).
  static constexpr double kElevationBin = 0.5;
  /// \brief A point is hidden when it lies more than kBehindRatio times the range of the nearest
  ///        read point of its bin plus kBehindMargin [m] from the origin.
  static constexpr double kBehindRatio = 1.5;
  static constexpr double kBehindMargin = 1.0;
  /// \brief Points nearer the origin than this are not read (the sensor's own mount) [m].
  static constexpr double kMinRange = 1.0;
  /// \brief At least this share hidden: the origin is no single viewpoint of the cloud. Single
  ///        scans measure 0.000-0.037, merged clouds 0.098 and up (docs/normal_method.md).
  static constexpr double kHiddenCut = 0.06;

  /// \brief A stream's share is measured again on its first scan, every kMeasureEvery-th, and
  ///        when the point count moves by more than a tenth or the origin moves; kept otherwise
  ///        (a sensor's view does not change from scan to scan; about 0.25 ms a measurement).
  static constexpr int kMeasureEvery = 16;

  /// \brief The share of the read points (finite, beyond kMinRange) hidden from `origin`; 0
  ///        for fewer than 64 such points.
  double hiddenShare(const CloudView& cloud, const float origin[3]);
  /// \brief hiddenShare(), or the share kept from an earlier scan of the same stream (above).
  double streamShare(const CloudView& cloud, const float origin[3]);

 private:
  double kept_ = 0.0;  // the last measured share
  StreamKeep keep_{kMeasureEvery};

  std::vector<std::uint32_t> bin_;   // per read point: its direction bin
  std::vector<float> range_;         // per read point: its range [m]
  std::vector<float> nearest_;       // per bin: the least range read, +inf none
  std::vector<std::uint32_t> used_;  // bins set by the last call (reset on the next)
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_AIRBORNE_ORIGIN_VIEW_H
