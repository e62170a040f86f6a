#ifndef GROUND_FILTER_PARAM_TABLE_H
#define GROUND_FILTER_PARAM_TABLE_H

#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "ground_filter/param_parse.h"

namespace ground_filter {

/// \brief One row of a parameter table, generated from the method's parameter definition file
///        (include/ground_filter/params/*.def, GF_PARAM_ROW of params/param_def.h), which the
///        .cfg files read too. set(), validate() and the log line read the rows. (C++14: no
///        std::variant, so installed headers stay usable from C++14 packages.)
template <class P>
struct ParamSpec {
  /// \brief Type of the struct member.
  enum class Type { kDouble, kInt, kBool, kString };

  /// \brief A row for member `m` of P (or of a base of P): a double or int member with its range
  ///        [lo, hi], a bool member (no range) or a string member (its values are checked by the
  ///        struct's validate()); `u` unit, `d` description, `pp` the paper's value.
  template <class M>
  ParamSpec(const char* n, M m, double lo, double hi, const char* u, const char* d,
            const char* pp = "")
      : name(n), min(lo), max(hi), unit(u), description(d), paper(pp) {
    bind(m);
  }

  const char* name;                     ///< parameter name (CLI, YAML, dynamic_reconfigure)
  Type type;                            ///< which of the members below is set
  double P::*as_double = nullptr;       ///< field of P (type kDouble)
  int P::*as_int = nullptr;             ///< field of P (type kInt)
  bool P::*as_bool = nullptr;           ///< field of P (type kBool)
  std::string P::*as_string = nullptr;  ///< field of P (type kString)
  double min;                           ///< smallest valid value (numbers only)
  double max;                           ///< largest valid value (numbers only)
  const char* unit;         ///< unit as written in the .cfg description ("m", "deg", "" = none)
  const char* description;  ///< what it does (the .cfg's text before the unit)
  const char* paper;        ///< the paper's value, "" = none

  /// \brief True for double and int members (the ones with a range).
  bool isNumber() const { return type == Type::kDouble || type == Type::kInt; }
  /// \brief The value of a number member of `p` as a double.
  double number(const P& p) const {
    return type == Type::kDouble ? p.*as_double : static_cast<double>(p.*as_int);
  }

 private:
  // Stores the member and its type (a member of a base converts to one of P; a member of any
  // other type matches no overload and does not compile).
  void bind(double P::*m) {
    type = Type::kDouble;
    as_double = m;
  }
  void bind(int P::*m) {
    type = Type::kInt;
    as_int = m;
  }
  void bind(bool P::*m) {
    type = Type::kBool;
    as_bool = m;
  }
  void bind(std::string P::*m) {
    type = Type::kString;
    as_string = m;
  }
};

/// \brief All parameters of one params struct, in the order of the .cfg file.
template <class P>
using ParamTable = std::vector<ParamSpec<P>>;

/// \brief Text of `spec`'s value in `p` (numbers as the shortest round-trip text).
template <class P>
std::string paramValueText(const ParamSpec<P>& spec, const P& p) {
  std::ostringstream out;
  switch (spec.type) {
    case ParamSpec<P>::Type::kDouble:
      out << p.*spec.as_double;
      break;
    case ParamSpec<P>::Type::kInt:
      out << p.*spec.as_int;
      break;
    case ParamSpec<P>::Type::kBool:
      out << (p.*spec.as_bool ? "true" : "false");
      break;
    case ParamSpec<P>::Type::kString:
      out << p.*spec.as_string;
      break;
  }
  return out.str();
}

/// \brief Sets parameter `name` of `p` from text.
/// \throws std::invalid_argument for an unknown name (listing the known ones) or a bad value.
template <class P>
void setParam(const ParamTable<P>& table, const char* method, const std::string& name,
              const std::string& value, P* p) {
  for (const auto& spec : table) {
    if (name != spec.name) continue;
    switch (spec.type) {
      case ParamSpec<P>::Type::kDouble:
        p->*spec.as_double = parseDoubleParam(name, value);
        break;
      case ParamSpec<P>::Type::kInt:
        p->*spec.as_int = parseIntParam(name, value);
        break;
      case ParamSpec<P>::Type::kBool:
        p->*spec.as_bool = parseBoolParam(name, value);
        break;
      case ParamSpec<P>::Type::kString:
        p->*spec.as_string = value;
        break;
    }
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
    if (spec.isNumber()) checkRange(spec.name, spec.number(p), spec.min, spec.max, spec.unit);
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

/// \brief Base of a params struct `P` whose table drives set() and describe() (CRTP). `P`
///        provides `static const ParamTable<P>& table()`, `static const char* method()` (the
///        method's name in messages) and its own `validate()` (checkParamRanges() plus any
///        cross-field rule): GF_TABLE_PARAMS_MEMBERS declares the three.
template <class P>
struct TableParams {
  /// \brief Sets one field from text (CLI `--set NAME=VALUE`).
  /// \throws std::invalid_argument for an unknown name or a malformed value.
  void set(const std::string& name, const std::string& value) {
    setParam(P::table(), P::method(), name, value, static_cast<P*>(this));
  }
  /// \brief "name=value ..." of every parameter (log line).
  std::string describe() const { return describeParams(P::table(), static_cast<const P&>(*this)); }
};

}  // namespace ground_filter

/// \brief Declares the members a method's params struct `P` (a TableParams<P>) provides:
///        `void validate() const` (every field's range and the rules between fields; throws
///        std::invalid_argument naming the first bad field, its value and its range),
///        `static const ParamTable<P>& table()` (the parameter table behind set(), validate() and
///        describe(), which the method's .cfg must agree with) and `static const char* method()`,
///        which returns `NAME`, the method's name (messages, makeGroundFilter()).
#define GF_TABLE_PARAMS_MEMBERS(P, NAME)                \
  void validate() const;                                \
  static const ::ground_filter::ParamTable<P>& table(); \
  static const char* method() { return NAME; }

#endif  // GROUND_FILTER_PARAM_TABLE_H
