#ifndef GROUND_FILTER_PARAM_PARSE_H
#define GROUND_FILTER_PARAM_PARSE_H

#include <string>
#include <vector>

namespace ground_filter {

/// \brief Parses a finite double for parameter `name`.
/// \throws std::invalid_argument naming the parameter when `value` is not a number.
double parseDoubleParam(const std::string& name, const std::string& value);

/// \brief Parses an integer for parameter `name`.
/// \throws std::invalid_argument naming the parameter when `value` is not an integer.
int parseIntParam(const std::string& name, const std::string& value);

/// \brief Parses true/false/1/0/yes/no/on/off for parameter `name`.
/// \throws std::invalid_argument naming the parameter otherwise.
bool parseBoolParam(const std::string& name, const std::string& value);

/// \brief Throws std::invalid_argument("NAME = VALUE is out of range [lo, hi] UNIT") unless
///        lo <= value <= hi.
void checkRange(const char* name, double value, double lo, double hi, const char* unit);

/// \brief Throws std::invalid_argument("parameter 'NAME' = 'VALUE' is not one of: A, B") unless
///        `value` is one of `choices` (a string parameter with fixed values).
void checkChoice(const char* name, const std::string& value,
                 const std::vector<std::string>& choices);

}  // namespace ground_filter

#endif  // GROUND_FILTER_PARAM_PARSE_H
