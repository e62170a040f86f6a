#include "ground_filter/param_parse.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace ground_filter {

double parseDoubleParam(const std::string& name, const std::string& value) {
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (value.empty() || end == value.c_str() || *end != '\0' || !std::isfinite(v)) {
    throw std::invalid_argument("parameter '" + name + "': '" + value + "' is not a finite number");
  }
  return v;
}

int parseIntParam(const std::string& name, const std::string& value) {
  char* end = nullptr;
  const long v = std::strtol(value.c_str(), &end, 10);
  if (value.empty() || end == value.c_str() || *end != '\0' || v < -2147483647L ||
      v > 2147483647L) {
    throw std::invalid_argument("parameter '" + name + "': '" + value + "' is not an integer");
  }
  return static_cast<int>(v);
}

bool parseBoolParam(const std::string& name, const std::string& value) {
  std::string v = value;
  std::transform(v.begin(), v.end(), v.begin(), [](unsigned char c) { return std::tolower(c); });
  if (v == "1" || v == "true" || v == "yes" || v == "on") return true;
  if (v == "0" || v == "false" || v == "no" || v == "off") return false;
  throw std::invalid_argument("parameter '" + name + "': '" + value + "' is not a boolean");
}

void checkRange(const char* name, double value, double lo, double hi, const char* unit) {
  if (!(value >= lo && value <= hi)) {
    std::ostringstream os;
    os << "parameter '" << name << "' = " << value << " is out of range [" << lo << ", " << hi
       << "]" << (unit[0] ? " " : "") << unit;
    throw std::invalid_argument(os.str());
  }
}

void checkChoice(const char* name, const std::string& value,
                 const std::vector<std::string>& choices) {
  if (std::find(choices.begin(), choices.end(), value) != choices.end()) return;
  std::string known;
  for (const auto& c : choices) known += (known.empty() ? "" : ", ") + c;
  throw std::invalid_argument(std::string("parameter '") + name + "' = '" + value +
                              "' is not one of: " + known);
}

}  // namespace ground_filter
