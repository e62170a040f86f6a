// Stand-ins for the few ROS 2 names LimHyungTae/patchwork's patchwork.hpp touches, so that its
// header builds without ROS 2 (scripts/peers/patchwork_driver.cpp): a Node whose parameters come
// from a map filled by the driver, its logger, the logging macros and a Clock.
#ifndef GROUND_FILTER_PEERS_STANDIN_RCLCPP_HPP
#define GROUND_FILTER_PEERS_STANDIN_RCLCPP_HPP

#include <chrono>
#include <cstdio>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "../../driver_common.h"  // peers::trimmed(), peers::number()

namespace rclcpp {

/// \brief Parameters by their dotted name, as text; declare_parameter parses the one asked for.
class Node {
 public:
  std::map<std::string, std::string> params;
  std::vector<std::string> used;  // "name=value" of every parameter read from `params`

  template <typename T>
  T declare_parameter(const std::string& name, const T& fallback) {
    const auto it = params.find(name);
    if (it == params.end()) return fallback;
    used.push_back(name + "=" + it->second);
    return parse(name, it->second, static_cast<T*>(nullptr));
  }
  int get_logger() const { return 0; }

 private:
  /// YAML values may be quoted ("HDL-64E").
  static std::string trimmed(const std::string& s) { return peers::trimmed(s, " \t\r\"'"); }
  static double parse(const std::string& name, const std::string& v, double*) {
    return peers::number(name, trimmed(v));
  }
  static int parse(const std::string& name, const std::string& v, int*) {
    return static_cast<int>(parse(name, v, static_cast<double*>(nullptr)));
  }
  static bool parse(const std::string& name, const std::string& v, bool*) {
    const std::string t = trimmed(v);
    if (t == "true" || t == "True") return true;
    if (t == "false" || t == "False") return false;
    throw std::invalid_argument(name + "=" + v + ": not true or false");
  }
  static std::string parse(const std::string&, const std::string& v, std::string*) {
    return trimmed(v);
  }
  static std::vector<double> parse(const std::string& name, const std::string& v,
                                   std::vector<double>*) {
    std::string t = trimmed(v);
    if (t.size() < 2 || t.front() != '[' || t.back() != ']') {
      throw std::invalid_argument(name + "=" + v + ": not a list [a, b, ...]");
    }
    std::vector<double> out;
    std::stringstream items(t.substr(1, t.size() - 2));
    std::string item;
    while (std::getline(items, item, ',')) {
      out.push_back(parse(name, item, static_cast<double*>(nullptr)));
    }
    return out;
  }
};

/// \brief Wall-clock time, as rclcpp::Clock().now().seconds() reads it.
struct Time {
  double s;
  double seconds() const { return s; }
};
struct Clock {
  Time now() const {
    return {
        std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count()};
  }
};

}  // namespace rclcpp

// The peer's log lines go to stderr (stdout carries the driver's RESULT lines).
#define RCLCPP_INFO(logger, ...) \
  (static_cast<void>(logger), std::fprintf(stderr, __VA_ARGS__), std::fputc('\n', stderr))
#define RCLCPP_WARN(logger, ...) RCLCPP_INFO(logger, __VA_ARGS__)

#endif  // GROUND_FILTER_PEERS_STANDIN_RCLCPP_HPP
