// A sparse spinning sensor's scan lines (scan_lines.h): the normal filter's stage 1a, the voxel
// filter's step 10.

#include "common/scan_lines.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace ground_filter {

namespace {

constexpr double kDeg = 57.29577951308232;  // degrees a radian
constexpr double kHalfWedge = 1.5;          // [deg] half the azimuth of a wedge
constexpr double kMinRange = 4.0;           // [m] nearer points: the lasers' offsets blur angles
constexpr double kMaxRange = 80.0;          // [m]
constexpr double kSplit = 0.5;              // [deg] a larger elevation step starts another line
constexpr double kMinLine = 0.6;            // [deg] closer lines: a dense sensor, nothing to do
constexpr double kMinSeparation = 3.0;      // a line's gap to the nearer one, in its thicknesses
constexpr double kMinThickness = 0.05;      // [deg] floor of a line's thickness
constexpr std::size_t kMinLinePoints = 4;   // points of a cluster that counts as a line
constexpr std::size_t kMinLines = 6;        // clusters with a neighbour needed to measure
constexpr std::size_t kMaxWedgePoints = 20000;
constexpr float kBelowOrigin = 0.3f;  // [m] a point this far below the origin lies "below" it
// At least this share of the wedges' points below the origin: it is a sensor above the ground
// (a vehicle's frame on the ground sees its ground level with it, and everything else above).
// The middle of the sweeps' plateau, 0.5-0.9 (docs/normal_method.md).
constexpr double kMostBelow = 0.7;
// Raised lines at most this fraction as thick replace the origin's (plateau 0.5-0.9).
constexpr double kThinner = 0.7;
constexpr std::size_t kSearchPoints = 1000;

double median(std::vector<double>* v) {
  const std::size_t k = v->size() / 2;
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(k), v->end());
  return (*v)[k];
}

}  // namespace

double ScanLineMeter::gather(const CloudView& cloud, const float origin[3]) {
  std::vector<Raw>* raw = raw_;
  for (int w = 0; w < 4; ++w) raw[w].clear();
  // One cheap test a point in float (NaN fails it); the rest only for the ~3 % in a wedge.
  const float t = static_cast<float>(std::tan(kHalfWedge / kDeg));
  const float ox = origin[0], oy = origin[1], oz = origin[2];
  std::size_t kept = 0, below = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const float dx = cloud.x(i) - ox, dy = cloud.y(i) - oy;
    const float ax = std::fabs(dx), ay = std::fabs(dy);
    const bool on_x = ay < t * ax, on_y = ax < t * ay;
    if (!(on_x || on_y)) continue;
    const int w = on_x ? (dx > 0.f ? 0 : 1) : (dy > 0.f ? 2 : 3);
    const float along = on_x ? ax : ay, across = on_x ? dy : dx;
    const float dz = cloud.z(i) - oz;
    const float rho = std::sqrt(dx * dx + dy * dy);
    if (!(rho >= kMinRange && rho <= kMaxRange) || !std::isfinite(dz) ||
        raw[w].size() >= kMaxWedgePoints) {
      continue;
    }
    // Inside +-1.5 deg the azimuth is across / along within 0.03 %: no atan for it.
    raw[w].push_back({rho, dz, static_cast<float>(across / along * kDeg)});
    ++kept;
    below += dz < -kBelowOrigin;
  }
  return kept ? static_cast<double>(below) / static_cast<double>(kept) : 1.0;
}

ScanLines ScanLineMeter::linesAt(double raise, std::size_t every, double* thick) {
  *thick = 0.0;
  std::vector<Angles>* wedge = wedge_;
  const float up = static_cast<float>(raise);
  for (int w = 0; w < 4; ++w) {
    wedge[w].clear();
    const std::vector<Raw>& raw = raw_[w];
    for (std::size_t i = 0; i < raw.size(); i += every) {
      wedge[w].push_back(
          {static_cast<float>(std::atan((raw[i].dz - up) / raw[i].rho) * kDeg), raw[i].az});
    }
  }
  // Clusters of nearby elevations, one a line where it is thin; a thick one is a band of lines
  // closer than kSplit (the middle of a VLS-128, any dense sensor).
  std::vector<Cluster>& clusters = clusters_;
  std::vector<double>&az = az_, &d = d_;
  std::vector<Weighted>& measured = measured_;
  measured.clear();
  double thick_sum = 0.0;
  std::size_t thick_points = 0;
  for (int w = 0; w < 4; ++w) {
    std::vector<Angles>& pts = wedge[w];
    std::sort(pts.begin(), pts.end(), [](const Angles& a, const Angles& b) { return a.el < b.el; });
    clusters.clear();
    for (std::size_t a = 0; a < pts.size();) {
      std::size_t e = a + 1;
      while (e < pts.size() && pts[e].el - pts[e - 1].el <= kSplit) ++e;
      if (e - a >= kMinLinePoints) {
        az.clear();
        for (std::size_t j = a; j < e; ++j) az.push_back(pts[j].az);
        std::sort(az.begin(), az.end());
        d.clear();
        for (std::size_t j = 1; j < az.size(); ++j) d.push_back(az[j] - az[j - 1]);
        clusters.push_back({0.5 * (pts[a].el + pts[e - 1].el),
                            std::max(kMinThickness, double(pts[e - 1].el - pts[a].el)), median(&d),
                            e - a});
      }
      a = e;
    }
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      double gap = 1e9;
      if (c > 0) gap = std::min(gap, clusters[c].centre - clusters[c - 1].centre);
      if (c + 1 < clusters.size()) gap = std::min(gap, clusters[c + 1].centre - clusters[c].centre);
      if (gap > 1e8) continue;  // a lone cluster: no spacing to measure
      const bool line = gap >= kMinSeparation * clusters[c].thick;
      thick_sum += clusters[c].thick * static_cast<double>(clusters[c].points);
      thick_points += clusters[c].points;
      measured.push_back({line ? gap : 0.0, clusters[c].step, clusters[c].points});
    }
  }
  ScanLines lines;
  if (measured.size() < kMinLines) return lines;
  // The spacing of the lines the points lie on: the point-weighted median, so a dense band
  // holding most points keeps a scan "dense" however sparse its outer lines are.
  std::sort(measured.begin(), measured.end(),
            [](const Weighted& a, const Weighted& b) { return a.spacing < b.spacing; });
  std::size_t total = 0, seen = 0;
  for (const Weighted& m : measured) total += m.points;
  *thick = thick_sum / static_cast<double>(thick_points);
  double line = 0.0;
  for (const Weighted& m : measured) {
    seen += m.points;
    if (2 * seen >= total) {
      line = m.spacing;
      break;
    }
  }
  if (line < kMinLine) return lines;
  std::vector<double>& steps = steps_;
  steps.clear();
  for (const Weighted& m : measured) {
    if (m.spacing > 0.0) steps.push_back(m.step);
  }
  lines.line_deg = line;
  lines.firing_deg = median(&steps);
  lines.from[2] = raise;
  return lines;
}

ScanLines ScanLineMeter::measureAbove(const CloudView& cloud, const float origin[3]) {
  const double below = gather(cloud, origin);
  double thick;
  ScanLines best = linesAt(0.0, 1, &thick);
  // A sensor above the ground sees nearly all of its ground below it: its origin is the sensor.
  if (below >= kMostBelow) return best;
  // Seen from the sensor, each ring is one elevation whatever its points hit; from anywhere
  // else the ring's near and far returns part: the thinnest lines show where the sensor is.
  // Lines seen from the origin itself give way only to clearly thinner lines (they may be
  // parted rings; or the origin is the sensor, low over rising ground).
  // The heights are compared on at most kSearchPoints points a wedge (a dense sensor's wedges
  // hold up to kMaxWedgePoints); the lines of the one chosen are measured on all of them.
  const double origin_thick = thick;
  std::size_t most = 0;
  for (const std::vector<Raw>& raw : raw_) most = std::max(most, raw.size());
  const std::size_t every = most / kSearchPoints + 1;
  double raise = 0.0, raised_thick = 0.0;
  const int steps = static_cast<int>(std::lround(kMaxRaise / kRaiseStep));
  for (int k = 1; k <= steps; ++k) {
    const ScanLines l = linesAt(k * kRaiseStep, every, &thick);
    if (l.ratio() > 0.0 && (raise == 0.0 || thick < raised_thick)) {
      raise = k * kRaiseStep;
      raised_thick = thick;
    }
  }
  if (raise > 0.0 && (best.ratio() == 0.0 || raised_thick < kThinner * origin_thick)) {
    const ScanLines raised = linesAt(raise, 1, &thick);
    if (raised.ratio() > 0.0) best = raised;
  }
  return best;
}

ScanLines ScanLineMeter::measureAround(const CloudView& cloud, const float origin[3]) {
  ScanLines lines = measureAbove(cloud, origin);
  float c[3];
  if (lines.ratio() > 0.0 || !centre_.find(cloud, c)) return lines;
  const double dx = c[0] - origin[0], dy = c[1] - origin[1];
  if (dx * dx + dy * dy < kMinShift * kMinShift) return lines;
  ScanLines there = measureAbove(cloud, c);
  if (!(there.ratio() > 0.0)) return lines;
  for (int a = 0; a < 3; ++a) there.from[a] += c[a] - origin[a];
  return there;
}

const ScanLines& StreamScanLines::of(const CloudView& cloud, const float origin[3]) {
  if (!kept_.keep.keep(cloud.size(), origin)) {
    kept_.lines = meter_.measureAround(cloud, origin);
    kept_.keep.setEvery(kept_.lines.line_deg > 0.0 ? kLinesEvery : kDenseEvery);
  }
  return kept_.lines;
}

}  // namespace ground_filter
