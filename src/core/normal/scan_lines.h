// Private to the normal filter: how far apart a spinning sensor's scan lines lie compared with
// its firings along a line (normal_ground_filter.cpp widens the sample stride from it).
#ifndef GROUND_FILTER_SRC_CORE_NORMAL_SCAN_LINES_H
#define GROUND_FILTER_SRC_CORE_NORMAL_SCAN_LINES_H

#include <cstddef>
#include <vector>

#include "ground_filter/cloud_view.h"

namespace ground_filter {
namespace normal {

/// \brief The scan lines of a spinning sensor as seen from its origin [deg]: both 0 when the
///        cloud shows no clean, sparse lines (a dense sensor, no lines, no sensor at the origin).
struct ScanLines {
  double line_deg = 0.0;    ///< median elevation between neighbouring lines
  double firing_deg = 0.0;  ///< median azimuth between neighbouring points of a line
  /// \brief line_deg / firing_deg, 0 without clean lines.
  double ratio() const { return firing_deg > 0.0 ? line_deg / firing_deg : 0.0; }
};

/// \brief Measures ScanLines, keeping its buffers from call to call (no allocation once sized).
class ScanLineMeter {
 public:
  /// \brief ScanLines of `cloud` seen from `origin` (the sensor, in the view's frame). A ray's
  ///        elevation does not depend on what it hits, so a line (ring) of a level sensor is
  ///        one elevation: in four 3 deg wedges of azimuth (along +-x and +-y, points 4-80 m
  ///        away horizontally) the points' elevations form clusters, one a line. The line
  ///        spacing is the point-weighted median gap of the clusters much farther apart than
  ///        they are thick (a band of lines closer than 0.5 deg, as in any dense sensor, counts
  ///        as dense); the spacing along a line is the median azimuth step inside them.
  ScanLines measure(const CloudView& cloud, const float origin[3]);

 private:
  struct Angles {
    float el, az;  // elevation, azimuth within the wedge [deg]
  };
  struct Cluster {
    double centre, thick, step;  // [deg]
    std::size_t points;
  };
  struct Weighted {
    double spacing;  // gap to the nearer neighbouring cluster; 0: not a clean line
    double step;
    std::size_t points;
  };
  std::vector<Angles> wedge_[4];
  std::vector<Cluster> clusters_;
  std::vector<double> az_, d_, steps_;
  std::vector<Weighted> measured_;
};

/// \brief `stride`, doubled (at most kMaxSampleStride) while lines.ratio() / stride exceeds
///        `max_ratio`: the sampled points of a line then lie at least 1 / max_ratio of the
///        line spacing apart, and a point's K nearest samples reach the next line. `stride`
///        itself when max_ratio is 0 or no lines were found.
int strideForScanLines(const ScanLines& lines, double max_ratio, int stride);

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_SCAN_LINES_H
