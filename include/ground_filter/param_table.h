#ifndef GROUND_FILTER_PARAM_TABLE_H
#define GROUND_FILTER_PARAM_TABLE_H

#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "ground_filter/param_parse.h"

namespace ground_filter {

/// \brief One row of a parameter table: the single place a parameter's name, struct member,
///        range, unit and description are written. set(), validate(), the log line, the docs
///        table and the drift test against the .cfg files all read it.
template <class P>
struct ParamSpec {
  /// \brief The struct member the row reads and writes.
  using Member = std::variant<double P::*, int P::*, bool P::*, std::string P::*>;
  const char* name;         ///< parameter name (CLI, YAML, dynamic_reconfigure)
  Member member;            ///< field of P
  double min;               ///< smallest valid value (numbers only)
  double max;               ///< largest valid value (numbers only)
  const char* unit;         ///< unit as written in the .cfg description ("m", "deg", "" = none)
  const char* description;  ///< one line: what it does
};

/// \brief All parameters of one params struct, in the order of the .cfg file.
template <class P>
using ParamTable = std::vector<ParamSpec<P>>;

/// \brief Text of `spec`'s value in `p` (numbers as the shortest round-trip text).
template <class P>
std::string paramValueText(const ParamSpec<P>& spec, const P& p) {
  std::ostringstream out;
  std::visit(
      [&](auto member) {
        using T = std::decay_t<decltype(p.*member)>;
        if constexpr (std::is_same_v<T, bool>) {
          out << (p.*member ? "true" : "false");
        } else {
          out << p.*member;
        }
      },
      spec.member);
  return out.str();
}

/// \brief Sets parameter `name` of `p` from text.
/// \throws std::invalid_argument for an unknown name (listing the known ones) or a bad value.
template <class P>
void setParam(const ParamTable<P>& table, const char* method, const std::string& name,
              const std::string& value, P* p) {
  for (const auto& spec : table) {
    if (name != spec.name) continue;
    std::visit(
        [&](auto member) {
          using T = std::decay_t<decltype(p->*member)>;
          if constexpr (std::is_same_v<T, double>) {
            p->*member = parseDoubleParam(name, value);
          } else if constexpr (std::is_same_v<T, int>) {
            p->*member = parseIntParam(name, value);
          } else if constexpr (std::is_same_v<T, bool>) {
            p->*member = parseBoolParam(name, value);
          } else {
            p->*member = value;
          }
        },
        spec.member);
    return;
  }
  std::string known;
  for (const auto& spec : table) known += (known.empty() ? "" : ", ") + std::string(spec.name);
  throw std::invalid_argument("unknown parameter '" + name + "' for method " + method +
                              " (known: " + known + ")");
}

/// \brief Checks the range of every numeric row.
/// \throws std::invalid_argument naming the first bad parameter, its value and its range.
template <class P>
void checkParamRanges(const ParamTable<P>& table, const P& p) {
  for (const auto& spec : table) {
    std::visit(
        [&](auto member) {
          using T = std::decay_t<decltype(p.*member)>;
          if constexpr (std::is_same_v<T, double> || std::is_same_v<T, int>) {
            checkRange(spec.name, static_cast<double>(p.*member), spec.min, spec.max, spec.unit);
          }
        },
        spec.member);
  }
}

/// \brief "name=value name=value ..." of every row (the nodelets' log line).
template <class P>
std::string describeParams(const ParamTable<P>& table, const P& p) {
  std::string out;
  for (const auto& spec : table) {
    out += (out.empty() ? "" : " ") + std::string(spec.name) + "=" + paramValueText(spec, p);
  }
  return out;
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_PARAM_TABLE_H
