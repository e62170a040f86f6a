#ifndef GROUND_FILTER_SRC_NODELETS_PARAMS_FROM_CONFIG_H
#define GROUND_FILTER_SRC_NODELETS_PARAMS_FROM_CONFIG_H

#include <boost/any.hpp>
#include <string>

#include "ground_filter/param_table.h"

namespace ground_filter {

/// \brief Params from a generated dynamic_reconfigure Config through the params struct's table:
///        every table row takes the cfg value of the same name (no validation). cfg parameters
///        that are not in the table (the nodelet's own, e.g. max_range) are left to the caller;
///        test_param_tables checks that table and cfg agree.
template <class Params, class Config>
Params paramsFromConfigTable(const Config& config) {
  using Type = typename ParamSpec<Params>::Type;
  Params p;
  for (const auto& desc : Config::__getParamDescriptions__()) {
    for (const auto& spec : Params::table()) {
      if (desc->name != spec.name) continue;
      boost::any value;
      desc->getValue(config, value);
      switch (spec.type) {
        case Type::kDouble:
          p.*spec.as_double = boost::any_cast<double>(value);
          break;
        case Type::kInt:
          p.*spec.as_int = boost::any_cast<int>(value);
          break;
        case Type::kBool:
          p.*spec.as_bool = boost::any_cast<bool>(value);
          break;
        case Type::kString:
          p.*spec.as_string = boost::any_cast<std::string>(value);
          break;
      }
    }
  }
  return p;
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_PARAMS_FROM_CONFIG_H
