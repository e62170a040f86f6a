// Coordinate lattice of a cloud (normal/lattice.h).

#include "normal/lattice.h"

#include <algorithm>
#include <cmath>

namespace ground_filter {
namespace normal {

constexpr std::size_t LatticeMeter::kSamples;
constexpr double LatticeMeter::kMinStep;
constexpr std::size_t LatticeMeter::kMinGaps;

double LatticeMeter::axisStep(const CloudView& cloud, int axis, std::size_t samples,
                              std::size_t min_gaps) {
  const std::size_t n = cloud.size();
  const std::size_t stride = std::max<std::size_t>(1, n / samples);
  values_.clear();
  for (std::size_t i = 0; i < n; i += stride) {
    float p[3];
    if (cloud.get(i, &p[0], &p[1], &p[2])) values_.push_back(p[axis]);
  }
  std::sort(values_.begin(), values_.end());
  double least = 0.0;
  std::size_t gaps = 0;
  for (std::size_t i = 1; i < values_.size(); ++i) {
    const double g = static_cast<double>(values_[i]) - values_[i - 1];
    if (g <= 0.0) continue;
    least = gaps == 0 ? g : std::min(least, g);
    ++gaps;
  }
  if (gaps < min_gaps || least < kMinStep) return 0.0;
  for (std::size_t i = 1; i < values_.size(); ++i) {
    const double r = (static_cast<double>(values_[i]) - values_[i - 1]) / least;
    if (std::fabs(r - std::round(r)) > 0.05) return 0.0;
  }
  return least;
}

bool LatticeMeter::measure(const CloudView& cloud, double step[3]) {
  bool any = false;
  for (int a = 0; a < 3; ++a) {
    // A small sample first: natural coordinates fail it at once (their gaps are no multiples
    // of the least), so the full one runs only on a lattice.
    step[a] = axisStep(cloud, a, kSamples / 8, kMinGaps / 4) > 0.0
                  ? axisStep(cloud, a, kSamples, kMinGaps)
                  : 0.0;
    any = any || step[a] > 0.0;
  }
  return any;
}

}  // namespace normal
}  // namespace ground_filter
