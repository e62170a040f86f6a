#include "ground_filter/normal_ground_filter_params.h"

#include <stdexcept>

#include "airborne/shared_param_rows.h"
#include "ground_filter/neighbor_search.h"

namespace ground_filter {

void NormalGroundFilterParams::validate() const {
  // The angle window must contain the vertical (90 deg) and reach at most 90 deg from it: the
  // table's ranges (checked first) say exactly that.
  checkSharedParams(*this);
  if (veg_min_height > veg_max_height) {
    throw std::invalid_argument("parameter 'veg_min_height' must not exceed veg_max_height");
  }
  checkChoice("knn_backend", knn_backend, neighborSearchBackends());
}

// The rows come from include/ground_filter/params/normal_params.def, which
// cfg/NormalGroundFilter.cfg reads too.
#define GF_METHOD_PARAMS NormalGroundFilterParams
#define GF_METHOD_PARAMS_DEF "ground_filter/params/normal_params.def"
#include "airborne/method_param_table.inc"

}  // namespace ground_filter
