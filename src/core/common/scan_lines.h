// Shared by the methods: how far apart a spinning sensor's scan lines lie compared with its
// firings along a line (the normal filter widens its sample stride from it; the voxel filter's
// step 10 tells a wall's lowest line from the ground with it).
#ifndef GROUND_FILTER_SRC_CORE_COMMON_SCAN_LINES_H
#define GROUND_FILTER_SRC_CORE_COMMON_SCAN_LINES_H

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/densest_centre.h"
#include "common/stream_keep.h"
#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief The scan lines of a spinning sensor as seen from its origin [deg]: both 0 when the
///        cloud shows no clean, sparse lines (a dense sensor, no lines, no sensor at the origin).
struct ScanLines {
  double line_deg = 0.0;    ///< median elevation between neighbouring lines
  double firing_deg = 0.0;  ///< median azimuth between neighbouring points of a line
  /// Where the lines were seen from, relative to the origin [m]: 0 0 0 (the origin); 0 0 h
  /// where the origin lies on the ground below the sensor (a base frame, measureAbove()); or a
  /// sensor found away from the origin (a scan in a map frame, measureAround()).
  double from[3] = {0.0, 0.0, 0.0};
  /// \brief line_deg / firing_deg, 0 without clean lines.
  double ratio() const { return firing_deg > 0.0 ? line_deg / firing_deg : 0.0; }
  /// \brief The sensor the lines were seen from, `origin` + `from`, into `out`; false (out
  ///        untouched) where the origin is not finite.
  bool sensor(const float origin[3], float out[3]) const {
    if (!(std::isfinite(origin[0]) && std::isfinite(origin[1]) && std::isfinite(origin[2]))) {
      return false;
    }
    for (int a = 0; a < 3; ++a) out[a] = static_cast<float>(origin[a] + from[a]);
    return true;
  }
};

/// \brief The lowest scan line on a wall or a car's side (the voxel filter's step 10, the
///        normal filter's step 7): a hit that passed for ground and the next hit straight above
///        it lie on one upright surface where the sensor sees them less than kLineSpan lines
///        apart (no line passed between them).
struct WallLines {
  /// \brief Most elevation between the two hits, in scan lines: one line and a margin. At 1.0
  ///        two hits on a wall fail as often as they pass; from 1.5 the real sparse scans at
  ///        hand (KITTI thinned to every 4th / 2nd ring) lose 0.06-0.1, their lower block's
  ///        lines lying 1.5 median spacings apart; the generated scans are flat from 1.1-1.2 to
  ///        2-2.5 (docs: voxel_method.md, normal_method.md).
  static constexpr double kLineSpan = 1.2;
  /// \brief Most height of the upper hit above the lower one [m] (a car's or a wall's next line).
  static constexpr double kMaxRise = 2.5;
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
  ///        But where fewer than 70 % of the wedges' points lie below the origin (a frame on
  ///        the ground: base_link, base_footprint, with the sensor on a mast above it, whose
  ///        rings the origin sees parted), the lines seen from the origin or from kRaiseStep ..
  ///        kMaxRaise above it: of the heights that show lines, the one whose lines are
  ///        thinnest (a ring is one elevation only seen from its sensor), where they are at
  ///        most 0.7 times as thick as the origin's (or the origin shows none).
  ScanLines measureAbove(const CloudView& cloud, const float origin[3]);
  /// \brief measureAbove(); where it finds no lines, the same from the ground below the centre
  ///        of the cloud's densest area when that lies kMinShift or more from the origin: a
  ///        spinning sensor's points are densest around it, so a single scan in a map or odom
  ///        frame (a LIO's registered scan) shows its lines from there.
  ScanLines measureAround(const CloudView& cloud, const float origin[3]);
  /// \brief The densest area's centre lies at least this far from the origin (x/y) [m].
  static constexpr double kMinShift = 2.0;

  /// \brief Heights above the origin tried by measureAbove() [m]: every kRaiseStep up to
  ///        kMaxRaise, where a vehicle's or robot's sensor sits above its base frame.
  static constexpr double kRaiseStep = 0.25;
  static constexpr double kMaxRaise = 3.5;

 private:
  struct Raw {
    float rho, dz, az;  // horizontal range [m], z above the origin [m], azimuth in the wedge
  };
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
  // The wedges' points seen from `origin` into raw_; returns the share below it by 0.3 m.
  double gather(const CloudView& cloud, const float origin[3]);
  // The lines of every `every`-th point of raw_ seen from `raise` above the origin; *thick:
  // the clusters' mean thickness, point-weighted [deg].
  ScanLines linesAt(double raise, std::size_t every, double* thick);
  DensestCentre centre_;
  std::vector<Raw> raw_[4];
  std::vector<Angles> wedge_[4];
  std::vector<Cluster> clusters_;
  std::vector<double> az_, d_, steps_;
  std::vector<Weighted> measured_;
};

/// \brief A stream's ScanLines (ScanLineMeter::measureAround()), measured on its first scan and
///        again where its sensor may have changed (StreamKeep: the point count moves by more than
///        a tenth, the origin moves), every kLinesEvery-th scan, or every kDenseEvery-th where
///        the last measurement found no sparse lines: a dense sensor has nothing that uses them,
///        and the measurement reads the whole cloud (4 ms a KITTI frame, 7 ms an OS-128 scan,
///        about as long as a filter's other stages), so under 1 % of its scans pay it.
class StreamScanLines {
 public:
  static constexpr int kLinesEvery = 16;
  static constexpr int kDenseEvery = 256;
  /// \brief What a stream keeps between scans (saved and restored where a run is dropped).
  struct Kept {
    ScanLines lines;
    StreamKeep keep{kLinesEvery};
  };

  /// \brief The lines of `cloud` seen from `origin` (finite), kept or measured again.
  const ScanLines& of(const CloudView& cloud, const float origin[3]);
  /// \brief The state kept; restore() takes a copy back.
  const Kept& kept() const { return kept_; }
  void restore(const Kept& kept) { kept_ = kept; }

 private:
  ScanLineMeter meter_;
  Kept kept_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_SCAN_LINES_H
