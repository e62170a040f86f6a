#ifndef GROUND_FILTER_PARAMS_PARAM_DEF_H
#define GROUND_FILTER_PARAMS_PARAM_DEF_H

// Expansions of the parameter definition files (include/ground_filter/params/*.def, one
// GF_PARAM(type, name, default, min, max, unit, group, paper, description) line per parameter).
// A user of a .def defines GF_PARAM as one of the macros below (or its own), includes the .def
// and undefines GF_PARAM again. Plain preprocessor, no includes: usable from C++14 and nvcc.

/// \brief The C++ type of a .def type word.
#define GF_PARAM_TYPE_double double
#define GF_PARAM_TYPE_int int
#define GF_PARAM_TYPE_bool bool
#define GF_PARAM_TYPE_string std::string

/// \brief A struct member with its default, every type.
#define GF_PARAM_MEMBER(type, name, def, ...) GF_PARAM_TYPE_##type name = def;

/// \brief A struct member with its default for the plain types (number, bool) only: the
///        members of a settings struct that host and device code share.
#define GF_PARAM_PLAIN_MEMBER(type, name, def, ...) GF_PARAM_PLAIN_##type(name, def)
#define GF_PARAM_PLAIN_double(name, def) double name = def;
#define GF_PARAM_PLAIN_int(name, def) int name = def;
#define GF_PARAM_PLAIN_bool(name, def) bool name = def;
#define GF_PARAM_PLAIN_string(name, def)

/// \brief A struct member with its default for the string type only (the rest of a struct
///        whose plain members come from GF_PARAM_PLAIN_MEMBER).
#define GF_PARAM_STRING_MEMBER(type, name, def, ...) GF_PARAM_STRING_##type(name, def)
#define GF_PARAM_STRING_double(name, def)
#define GF_PARAM_STRING_int(name, def)
#define GF_PARAM_STRING_bool(name, def)
#define GF_PARAM_STRING_string(name, def) std::string name = def;

/// \brief A ParamSpec<P> row (ground_filter/param_table.h) of the struct `P` in scope.
#define GF_PARAM_ROW(type, name, def, lo, hi, unit, group, paper, desc) \
  {#name, &P::name, lo, hi, unit, desc, paper},

#endif  // GROUND_FILTER_PARAMS_PARAM_DEF_H
