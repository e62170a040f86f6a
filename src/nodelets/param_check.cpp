#include "param_check.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace ground_filter {

namespace {

const char* typeName(ParamCheck::Type t) {
  switch (t) {
    case ParamCheck::Type::kDouble:
      return "a number";
    case ParamCheck::Type::kInt:
      return "an integer";
    case ParamCheck::Type::kBool:
      return "true or false";
    case ParamCheck::Type::kString:
      return "a string";
    case ParamCheck::Type::kDoubleList:
      return "a list of numbers";
  }
  return "?";
}

bool isNumber(const XmlRpc::XmlRpcValue& v) {
  return v.getType() == XmlRpc::XmlRpcValue::TypeDouble ||
         v.getType() == XmlRpc::XmlRpcValue::TypeInt;
}

double number(XmlRpc::XmlRpcValue v) {  // by value: the casts are non-const
  return v.getType() == XmlRpc::XmlRpcValue::TypeInt ? static_cast<int>(v) : static_cast<double>(v);
}

std::string show(XmlRpc::XmlRpcValue v) {
  std::string s = v.toXml();
  // <value><string>abc</string></value> -> abc, short enough for a log line
  for (const char* tag : {"<value>", "</value>"}) {
    for (std::size_t p; (p = s.find(tag)) != std::string::npos;)
      s.erase(p, std::string(tag).size());
  }
  if (v.getType() == XmlRpc::XmlRpcValue::TypeString) s = "'" + static_cast<std::string>(v) + "'";
  if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble ||
      v.getType() == XmlRpc::XmlRpcValue::TypeInt) {
    std::ostringstream o;
    o << number(v);
    s = o.str();
  }
  if (v.getType() == XmlRpc::XmlRpcValue::TypeBoolean) s = static_cast<bool>(v) ? "true" : "false";
  return s.size() > 60 ? s.substr(0, 57) + "..." : s;
}

bool typeOk(const XmlRpc::XmlRpcValue& v, ParamCheck::Type t) {
  switch (t) {
    case ParamCheck::Type::kDouble:
      return isNumber(v);
    case ParamCheck::Type::kInt:
      return v.getType() == XmlRpc::XmlRpcValue::TypeInt;
    case ParamCheck::Type::kBool:
      return v.getType() == XmlRpc::XmlRpcValue::TypeBoolean;
    case ParamCheck::Type::kString:
      return v.getType() == XmlRpc::XmlRpcValue::TypeString;
    case ParamCheck::Type::kDoubleList: {
      if (v.getType() != XmlRpc::XmlRpcValue::TypeArray) return false;
      XmlRpc::XmlRpcValue a = v;
      for (int i = 0; i < a.size(); ++i) {
        if (!isNumber(a[i])) return false;
      }
      return true;
    }
  }
  return false;
}

// Edit distance, for "did you mean" on an unknown key.
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] != b[j - 1] ? 1 : 0)});
      diag = up;
    }
  }
  return row[b.size()];
}

}  // namespace

std::vector<ParamCheck> baseParamChecks() {
  using T = ParamCheck::Type;
  auto p = [](const char* name, T type) {
    ParamCheck c;
    c.name = name;
    c.type = type;
    return c;
  };
  // Numbers with a range: a value outside is refused like a dynamic_reconfigure one (ERROR
  // naming the key, the default stays), not clamped in silence.
  auto r = [&p](const char* name, T type, double min, double max) {
    ParamCheck c = p(name, type);
    c.ranged = true;
    c.min = min;
    c.max = max;
    return c;
  };
  return {r("queue_size", T::kInt, 1, 1000),
          p("lazy", T::kBool),
          p("verbose_connection", T::kBool),
          p("duration_to_warn_no_connection", T::kDouble),
          p("gravity_frame", T::kString),
          r("tf_timeout", T::kDouble, 0.0, 10.0),
          r("diagnostic_period", T::kDouble, 0.01, 3600.0),
          r("malloc_trim_period", T::kDouble, 0.0, 3600.0),
          p("body_box", T::kDoubleList)};
}

std::vector<std::string> checkPrivateParams(const std::map<std::string, XmlRpc::XmlRpcValue>& set,
                                            const std::vector<ParamCheck>& known,
                                            std::vector<std::string>* refused_keys) {
  std::vector<std::string> errors;
  for (const auto& kv : set) {
    const std::string& key = kv.first;
    const ParamCheck* spec = nullptr;
    for (const ParamCheck& k : known) {
      if (k.name == key) spec = &k;
    }
    std::string why;
    if (!spec) {
      const ParamCheck* near = nullptr;
      std::size_t best = 4;  // suggest only close names
      for (const ParamCheck& k : known) {
        const std::size_t d = editDistance(key, k.name);
        if (d < best) best = d, near = &k;
      }
      // One short line: the full list of names (~1 kB) per key flooded the log when a YAML of
      // the other method was loaded.
      if (near) {
        why = "unknown parameter (did you mean " + near->name + "?)";
      } else {
        why = "unknown parameter of this method (another method's key? see the parameter table)";
      }
    } else if (!typeOk(kv.second, spec->type)) {
      why = show(kv.second) + " is not " + typeName(spec->type);
    } else if (spec->ranged) {
      const double v = number(kv.second);
      if (!(v >= spec->min && v <= spec->max)) {
        std::ostringstream o;
        o << show(kv.second) << " is outside [" << spec->min << ", " << spec->max << "]";
        why = o.str();
      }
    }
    if (!why.empty()) {
      errors.push_back(key + ": " + why);
      if (refused_keys) refused_keys->push_back(key);
    }
  }
  return errors;
}

}  // namespace ground_filter
