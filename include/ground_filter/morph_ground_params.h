#ifndef GROUND_FILTER_MORPH_GROUND_PARAMS_H
#define GROUND_FILTER_MORPH_GROUND_PARAMS_H

#include <string>

#include "ground_filter/params/param_def.h"

namespace ground_filter {

/// \brief Parameters of the airborne mode, a base of both methods' params structs: the same
///        morphological ground stage (after SMRF) runs in either filter when morph_ground is
///        set, with the method's plane_distance as its height threshold on flat ground; and
///        scan_type, which picks the mode per scan (docs/scan_types.md). Fields, defaults,
///        ranges: include/ground_filter/params/morph_params.def.
struct MorphGroundParams {
#define GF_PARAM GF_PARAM_MEMBER
#include "ground_filter/params/morph_params.def"
#undef GF_PARAM
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_MORPH_GROUND_PARAMS_H
