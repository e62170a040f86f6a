// Stage 1a of the normal filter: the scan lines' spacing (scan_lines.h).

#include "normal/scan_lines.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace normal {

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

double median(std::vector<double>* v) {
  const std::size_t k = v->size() / 2;
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(k), v->end());
  return (*v)[k];
}

}  // namespace

ScanLines ScanLineMeter::measure(const CloudView& cloud, const float origin[3]) {
  std::vector<Angles>* wedge = wedge_;
  for (int w = 0; w < 4; ++w) wedge[w].clear();
  // One cheap test a point in float (NaN fails it); the angles only for the ~3 % in a wedge.
  const float t = static_cast<float>(std::tan(kHalfWedge / kDeg));
  const float ox = origin[0], oy = origin[1], oz = origin[2];
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
        wedge[w].size() >= kMaxWedgePoints) {
      continue;
    }
    // Inside +-1.5 deg the azimuth is across / along within 0.03 %: no atan for it.
    wedge[w].push_back({static_cast<float>(std::atan(dz / rho) * kDeg),
                        static_cast<float>(across / along * kDeg)});
  }
  // Clusters of nearby elevations, one a line where it is thin; a thick one is a band of lines
  // closer than kSplit (the middle of a VLS-128, any dense sensor).
  std::vector<Cluster>& clusters = clusters_;
  std::vector<double>&az = az_, &d = d_;
  std::vector<Weighted>& measured = measured_;
  measured.clear();
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
  return lines;
}

int strideForScanLines(const ScanLines& lines, double max_ratio, int stride) {
  const double r = lines.ratio();
  if (!(max_ratio > 0.0) || !(r > 0.0)) return stride;
  while (stride < kMaxSampleStride && r / stride > max_ratio) {
    stride = doubledStride(stride);
  }
  return stride;
}

}  // namespace normal
}  // namespace ground_filter
