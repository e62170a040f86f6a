// Points hidden from the origin (airborne/origin_view.h).

#include "airborne/origin_view.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ground_filter {

constexpr std::size_t OriginView::kMaxRead;
constexpr double OriginView::kAzimuthBin;
constexpr double OriginView::kElevationBin;
constexpr double OriginView::kBehindRatio;
constexpr double OriginView::kBehindMargin;
constexpr double OriginView::kMinRange;
constexpr double OriginView::kHiddenCut;
constexpr int OriginView::kMeasureEvery;

namespace {

constexpr double kDegPerRad = 57.295779513082323;
// Bins of the pseudo-angles below: 4 units of azimuth make 360 deg; elevation runs over 2 units
// with 1 unit a radian at the horizon.
constexpr int kAzimuthBins = static_cast<int>(360.0 / OriginView::kAzimuthBin);
constexpr int kElevationBins = static_cast<int>(2.0 * kDegPerRad / OriginView::kElevationBin) + 1;

// Azimuth of (x, y) as a "diamond angle" in [0, 4): monotonic in the angle, no trigonometry.
// Straight up or down (x = y = 0, a TLS zenith): 0, any azimuth holds such a point.
inline float diamondAngle(float x, float y) {
  const float d = std::fabs(x) + std::fabs(y);
  if (!(d > 0.f)) return 0.f;
  if (y >= 0.f) return x >= 0.f ? y / d : 1.f - x / d;
  return x < 0.f ? 2.f - y / d : 3.f + x / d;
}

}  // namespace

double OriginView::hiddenShare(const CloudView& cloud, const float origin[3]) {
  const std::size_t n = cloud.size();
  const std::size_t step = std::max<std::size_t>(1, n / kMaxRead);
  nearest_.resize(static_cast<std::size_t>(kAzimuthBins) * kElevationBins,
                  std::numeric_limits<float>::infinity());
  for (std::uint32_t b : used_) nearest_[b] = std::numeric_limits<float>::infinity();
  used_.clear();
  bin_.clear();
  range_.clear();
  const float az_scale = static_cast<float>(kAzimuthBins / 4.0);
  const float el_scale = static_cast<float>(kDegPerRad / kElevationBin);
  const float o[3] = {origin[0], origin[1], origin[2]};
  for (std::size_t i = 0; i < n; i += step) {
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) continue;
    x -= o[0];
    y -= o[1];
    z -= o[2];
    const float rho = std::sqrt(x * x + y * y), r = std::sqrt(rho * rho + z * z);
    if (!(r >= static_cast<float>(kMinRange)) || !(r < std::numeric_limits<float>::infinity())) {
      continue;
    }
    // rho > 0 or |z| > 0 here: z / (rho + |z|) lies in [-1, 1], a radian a unit at the horizon.
    const int ia = std::min(kAzimuthBins - 1, static_cast<int>(diamondAngle(x, y) * az_scale));
    const int ie =
        std::min(kElevationBins - 1, static_cast<int>((z / (rho + std::fabs(z)) + 1.f) * el_scale));
    const std::uint32_t b = static_cast<std::uint32_t>(ie * kAzimuthBins + ia);
    if (std::isinf(nearest_[b])) used_.push_back(b);
    nearest_[b] = std::min(nearest_[b], r);
    bin_.push_back(b);
    range_.push_back(r);
  }
  if (bin_.size() < 64) return 0.0;
  std::size_t hidden = 0;
  const float ratio = static_cast<float>(kBehindRatio), margin = static_cast<float>(kBehindMargin);
  for (std::size_t k = 0; k < bin_.size(); ++k) {
    hidden += range_[k] > ratio * nearest_[bin_[k]] + margin;
  }
  return static_cast<double>(hidden) / static_cast<double>(bin_.size());
}

double OriginView::streamShare(const CloudView& cloud, const float origin[3]) {
  if (!keep_.keep(cloud.size(), origin)) kept_ = hiddenShare(cloud, origin);
  return kept_;
}

}  // namespace ground_filter
