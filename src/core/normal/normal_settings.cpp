#include "normal/normal_settings.h"

#include <algorithm>
#include <cmath>

namespace ground_filter {
namespace normal {

double minAbsNormalZ(const NormalGroundFilterParams& p) {
  const double max_tilt_deg = std::min(90.0 - p.min_normal_angle, p.max_normal_angle - 90.0);
  return std::cos(max_tilt_deg * M_PI / 180.0);
}

bool gpuSupports(const NormalGroundFilterParams& p) {
  // Segments and the bush-base rule run on the host only (k: the GPU executor's own limit).
  return !p.use_segments && !p.veg_filter;
}

}  // namespace normal
}  // namespace ground_filter
