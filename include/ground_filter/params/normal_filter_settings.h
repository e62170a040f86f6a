#ifndef GROUND_FILTER_PARAMS_NORMAL_FILTER_SETTINGS_H
#define GROUND_FILTER_PARAMS_NORMAL_FILTER_SETTINGS_H

// Plain fields only (no std::string, no includes beyond param_def.h): compiled by g++ and nvcc.

#include "ground_filter/params/param_def.h"

namespace ground_filter {

/// \brief The normal-vector method's number and bool parameters, with their defaults, as plain
///        fields generated from normal_params.def: a base of NormalGroundFilterParams, so a
///        params struct is one (no field-by-field copy) for code that cannot take std::string,
///        e.g. the CUDA device code.
struct NormalFilterSettings {
#define GF_PARAM GF_PARAM_PLAIN_MEMBER
#include "ground_filter/params/normal_params.def"
#undef GF_PARAM
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_PARAMS_NORMAL_FILTER_SETTINGS_H
