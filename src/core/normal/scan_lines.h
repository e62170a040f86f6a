// Private to the normal filter: how far apart a spinning sensor's scan lines lie compared with
// its firings along a line (normal_ground_filter.cpp widens the sample stride from it).
#ifndef GROUND_FILTER_SRC_CORE_NORMAL_SCAN_LINES_H
#define GROUND_FILTER_SRC_CORE_NORMAL_SCAN_LINES_H

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

/// \brief Measures ScanLines from `origin` (the sensor, in the view's frame). A ray's elevation
///        does not depend on what it hits, so a line (ring) of a level sensor is one elevation:
///        in four 3 deg wedges of azimuth (along +-x and +-y, points 4-80 m away horizontally)
///        the points' elevations form clusters, one a line. Only clusters much farther apart
///        than they are thick and at least 1 deg apart count (dense sensors, whose lines a
///        tilt or the lasers' offsets blur together, give none); the spacing along a line is the
///        median azimuth step inside the clusters.
ScanLines measureScanLines(const CloudView& cloud, const float origin[3]);

/// \brief `stride`, doubled (at most kMaxSampleStride) while lines.ratio() / stride exceeds
///        `max_ratio`: the sampled points of a line then lie at least 1 / max_ratio of the
///        line spacing apart, and a point's K nearest samples reach the next line. `stride`
///        itself when max_ratio is 0 or no lines were found.
int strideForScanLines(const ScanLines& lines, double max_ratio, int stride);

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_SCAN_LINES_H
