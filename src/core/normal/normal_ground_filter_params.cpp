#include "ground_filter/normal_ground_filter_params.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "airborne/scan_type.h"
#include "common/shared_param_rows.h"
#include "ground_filter/neighbor_search.h"
#include "normal/normal_settings.h"

namespace ground_filter {

// The rows come from include/ground_filter/params/normal_params.def, which
// cfg/NormalGroundFilter.cfg reads too.
const ParamTable<NormalGroundFilterParams>& NormalGroundFilterParams::table() {
  using P = NormalGroundFilterParams;
  static const ParamTable<P> rows = withSharedParamRows<P>({
#define GF_PARAM GF_PARAM_ROW
#include "ground_filter/params/normal_params.def"
#undef GF_PARAM
  });
  return rows;
}

void NormalGroundFilterParams::validate() const {
  // The angle window must contain the vertical (90 deg) and reach at most 90 deg from it: the
  // table's ranges say exactly that.
  checkParamRanges(table(), *this);
  validateScanTypeSetting(scan_type);
  if (veg_min_height > veg_max_height) {
    throw std::invalid_argument("parameter 'veg_min_height' must not exceed veg_max_height");
  }
  const auto backends = neighborSearchBackends();
  if (std::find(backends.begin(), backends.end(), knn_backend) == backends.end()) {
    std::string known;
    for (const auto& b : backends) known += (known.empty() ? "" : ", ") + b;
    throw std::invalid_argument("parameter 'knn_backend' = '" + knn_backend +
                                "' is not one of: " + known);
  }
}

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
