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

  /// \brief Checks every field's range (and the rules between fields).
  /// \throws std::invalid_argument naming the first bad field, its value and its range.
  void validate() const;
  /// \brief The parameter table (name, member, range, unit) behind set(), validate() and
  ///        describe(); cfg/NormalGroundFilter.cfg must agree with it.
  static const ParamTable<NormalGroundFilterParams>& table();
  /// \brief "normal": the method's name (messages, makeGroundFilter()).
  static const char* method() { return "normal"; }
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_NORMAL_GROUND_FILTER_PARAMS_H
