#ifndef GROUND_FILTER_NORMAL_GROUND_FILTER_PARAMS_H
#define GROUND_FILTER_NORMAL_GROUND_FILTER_PARAMS_H

#include <string>

#include "ground_filter/morph_ground_params.h"
#include "ground_filter/param_table.h"
#include "ground_filter/params/normal_filter_settings.h"

namespace ground_filter {

/// \brief Parameters of the normal-vector method (Diaz et al., section 2.3.1): name, type,
///        default, range, unit, paper value and meaning of each are in
///        include/ground_filter/params/normal_params.def (docs/parameters.md lists them). The
///        number and bool fields come from NormalFilterSettings, the strings (knn_backend) are
///        declared here; the airborne mode's morph_* and scan_type come from MorphGroundParams.
struct NormalGroundFilterParams : TableParams<NormalGroundFilterParams>,
                                  MorphGroundParams,
                                  NormalFilterSettings {
#define GF_PARAM GF_PARAM_STRING_MEMBER
#include "ground_filter/params/normal_params.def"
#undef GF_PARAM

  // validate(), table() (cfg/NormalGroundFilter.cfg must agree with it), method().
  GF_TABLE_PARAMS_MEMBERS(NormalGroundFilterParams, "normal")
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_NORMAL_GROUND_FILTER_PARAMS_H
