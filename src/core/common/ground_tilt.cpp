#include "common/ground_tilt.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>

#include "common/plane_fit.h"
#include "common/prefetch.h"

namespace ground_filter {

constexpr double GroundTiltEstimator::kRadius;
constexpr double GroundTiltEstimator::kNear;
constexpr double GroundTiltEstimator::kColumn;
constexpr double GroundTiltEstimator::kBand;
constexpr double GroundTiltEstimator::kMaxTilt;
constexpr double GroundTiltEstimator::kAbove;
constexpr double GroundTiltEstimator::kMaxHeight;
constexpr double GroundTiltEstimator::kFarRadius;
constexpr double GroundTiltEstimator::kFarColumn;
constexpr double GroundTiltEstimator::kBelowNear;
constexpr double GroundTiltEstimator::kMinShare;
constexpr std::size_t GroundTiltEstimator::kMinInliers;
constexpr int GroundTiltEstimator::kHypotheses;
constexpr std::size_t GroundTiltEstimator::kSample;

namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

// Columns of the plane n . p + d = 0 (p relative to the origin) whose lowest point lies within
// `band` of it: float lanes without branches (the compiler vectorises the loop).
std::size_t countNear(const float* x, const float* y, const float* z, std::size_t m,
                      const double n[3], double d, double band) {
  const float nx = static_cast<float>(n[0]), ny = static_cast<float>(n[1]);
  const float nz = static_cast<float>(n[2]), fd = static_cast<float>(d);
  const float b = static_cast<float>(band);
  std::size_t c = 0;
  for (std::size_t i = 0; i < m; ++i) {
    const float r = nx * x[i] + ny * y[i] + nz * z[i] + fd;
    c += std::fabs(r) <= b ? 1 : 0;
  }
  return c;
}

}  // namespace

GroundTilt GroundTiltEstimator::estimate(const CloudView& cloud, const float origin[3],
                                         double level_tilt) {
  GroundTilt near = fitLowest(cloud, origin, kNear, kRadius, kColumn);
  if (!near.found) return near;
  const bool high = near.height > kMaxHeight;
  // A level plane turns nothing: the farther ring is read only where the near plane would turn
  // the scan (a level scan costs one fit, as before).
  if (!high && !near.turns(level_tilt)) return near;
  // A sensor high above the plane sees its ground from farther out: read the lean there. A
  // leaning near plane over level ground that the ring sees lower down (object tops) gives way
  // to the ring's plane too; where the ring leans as well, the near plane stands (a sloped
  // world whose relief puts the ring's plane lower).
  GroundTilt far = fitLowest(cloud, origin, kRadius, kFarRadius, kFarColumn);
  far.high = true;
  if (high) return far;
  if (far.found && far.height > near.height + kBelowNear && !far.turns(level_tilt)) return far;
  return near;
}

GroundTilt GroundTiltEstimator::fitLowest(const CloudView& cloud, const float origin[3],
                                          double near, double radius, double column) {
  GroundTilt out;
  const int side = static_cast<int>(2.0 * radius / column);
  const float inf = std::numeric_limits<float>::infinity();
  low_.assign(static_cast<std::size_t>(side) * side * 3, inf);
  const double r2_lo = near * near, r2_hi = radius * radius;
  const double ox = origin[0], oy = origin[1], oz = origin[2];
  // Every step-th point (about kSample of them): a column's lowest point among them lies on
  // the ground as its lowest of all does, where the ground is seen at all.
  const std::size_t step = std::max<std::size_t>(1, cloud.size() / kSample);
  const std::size_t ahead = 16 * step * cloud.stride();  // a record per cache line: ask early
  for (std::size_t i = 0; i < cloud.size(); i += step) {
    prefetchAhead(cloud.data() + i * cloud.stride(), ahead);
    const float x = cloud.x(i), y = cloud.y(i), z = cloud.z(i);
    const double dx = x - ox, dy = y - oy, r2 = dx * dx + dy * dy;
    // NaN fails both tests, +-Inf the second.
    if (!(r2 >= r2_lo && r2 < r2_hi) || !std::isfinite(z)) continue;
    const int cx = std::min(side - 1, static_cast<int>((dx + radius) / column));
    const int cy = std::min(side - 1, static_cast<int>((dy + radius) / column));
    float* c = &low_[3 * (static_cast<std::size_t>(cy) * side + cx)];
    const float dz = static_cast<float>(z - oz);
    if (dz < c[2]) {
      c[0] = static_cast<float>(dx);
      c[1] = static_cast<float>(dy);
      c[2] = dz;
    }
  }
  // The occupied columns' lowest points, as x, y and z arrays of m each.
  std::size_t m = 0;
  for (std::size_t c = 0; c < low_.size(); c += 3) m += low_[c + 2] != inf;
  pts_.resize(3 * m);
  float *px = pts_.data(), *py = px + m, *pz = py + m;
  for (std::size_t c = 0, j = 0; c < low_.size(); c += 3) {
    if (low_[c + 2] == inf) continue;
    px[j] = low_[c];
    py[j] = low_[c + 1];
    pz[j++] = low_[c + 2];
  }
  out.columns = m;
  if (m < kMinInliers) return out;
  // RANSAC over the lowest points: a fixed generator (the same plane for the same scan).
  const double min_nz = std::cos(kMaxTilt * kDegToRad);
  std::uint64_t state = 0x9E3779B97F4A7C15ULL;
  auto next = [&state, m]() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<std::size_t>((state >> 33) % m);
  };
  std::size_t best = 0;
  double bn[3] = {0, 0, 1}, bd = 0.0;
  for (int h = 0; h < kHypotheses; ++h) {
    const std::size_t ia = next(), ib = next(), ic = next();
    const float a[3] = {px[ia], py[ia], pz[ia]}, b[3] = {px[ib], py[ib], pz[ib]};
    const float c[3] = {px[ic], py[ic], pz[ic]};
    const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
    const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
    double n[3] = {uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 1e-6)) continue;
    const double s = (n[2] < 0.0 ? -1.0 : 1.0) / len;
    for (double& v : n) v *= s;
    if (n[2] < min_nz) continue;
    const double d = -(n[0] * a[0] + n[1] * a[1] + n[2] * a[2]);
    if (d < -kAbove) continue;  // ground lies below the sensor (at 0), a ceiling above it
    const std::size_t k = countNear(px, py, pz, m, n, d, kBand);
    if (k > best) {
      best = k;
      std::copy(n, n + 3, bn);
      bd = d;
    }
  }
  if (best < kMinInliers || static_cast<double>(best) < kMinShare * static_cast<double>(m)) {
    return out;
  }
  // Least squares over the inliers, twice (the second time over the refined plane's).
  for (int pass = 0; pass < 2; ++pass) {
    PlaneAccumulator acc;
    for (std::size_t i = 0; i < m; ++i) {
      if (std::fabs(bn[0] * px[i] + bn[1] * py[i] + bn[2] * pz[i] + bd) <= kBand) {
        acc.add(px[i], py[i], pz[i]);
      }
    }
    Plane plane;  // fit(): normal z >= 0, origin 0, so n . p + d = 0 as the draws'
    if (!acc.fit(&plane) || plane.normal.z() < min_nz) break;
    for (int a = 0; a < 3; ++a) bn[a] = plane.normal[a];
    bd = plane.d;
  }
  out.inliers = countNear(px, py, pz, m, bn, bd, kBand);
  out.height = bd;
  out.found = bd >= -kAbove;
  std::copy(bn, bn + 3, out.normal);
  out.tilt_deg = std::acos(std::min(1.0, bn[2])) / kDegToRad;
  return out;
}

CloudView GroundTiltEstimator::level(const CloudView& cloud, const float origin[3],
                                     const GroundTilt& tilt, std::vector<float>* xyz) {
  // Rodrigues: the rotation about axis n x z by the angle between them takes n onto z.
  const double* n = tilt.normal;
  const double ax = n[1], ay = -n[0];  // n x (0, 0, 1)
  const double s = std::sqrt(ax * ax + ay * ay), c = n[2];
  double r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  if (s > 1e-12) {
    const double kx = ax / s, ky = ay / s, t = 1.0 - c;
    r[0] = c + kx * kx * t;
    r[1] = kx * ky * t;
    r[2] = ky * s;
    r[3] = kx * ky * t;
    r[4] = c + ky * ky * t;
    r[5] = -kx * s;
    r[6] = -ky * s;
    r[7] = kx * s;
    r[8] = c;
  }
  xyz->resize(3 * cloud.size());
  float* out = xyz->data();
  const double ox = origin[0], oy = origin[1], oz = origin[2];
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const double x = cloud.x(i) - ox, y = cloud.y(i) - oy, z = cloud.z(i) - oz;
    out[3 * i] = static_cast<float>(ox + r[0] * x + r[1] * y + r[2] * z);
    out[3 * i + 1] = static_cast<float>(oy + r[3] * x + r[4] * y + r[5] * z);
    out[3 * i + 2] = static_cast<float>(oz + r[6] * x + r[7] * y + r[8] * z);
  }
  return CloudView::packedXyz(out, cloud.size());
}

bool GroundTiltEstimator::applies(double level_tilt, bool registered, const float origin[3]) {
  return level_tilt > 0.0 && !registered && std::isfinite(origin[0]) && std::isfinite(origin[1]) &&
         std::isfinite(origin[2]);
}

void GroundTiltEstimator::appendTurnNote(double tilt_deg, double level_tilt, std::string* note) {
  char text[160];
  std::snprintf(text, sizeof text,
                "%sthe ground around the sensor leans %.1f deg in the cloud's frame "
                "(level_tilt %.1f): the scan was turned onto it",
                note->empty() ? "" : "; ", tilt_deg, level_tilt);
  note->append(text);
}

}  // namespace ground_filter
