#ifndef GROUND_FILTER_SRC_CORE_NORMAL_STAGE_TIMES_H
#define GROUND_FILTER_SRC_CORE_NORMAL_STAGE_TIMES_H

#include <chrono>
#include <string>
#include <utility>
#include <vector>

#include "common/threads_timing.h"

namespace ground_filter {
namespace normal {

/// \brief Stage wall times by name, summed over calls (segments), in first-seen order.
class StageTimes {
 public:
  /// \brief Adds `ms` to the stage `name` (appended when new).
  void add(const std::string& name, double ms) {
    for (auto& e : stages_) {
      if (e.first == name) {
        e.second += ms;
        return;
      }
    }
    stages_.emplace_back(name, ms);
  }
  /// \brief Forgets every stage; keeps the memory (short names fit std::string's inline
  ///        buffer), so a filter that reuses one allocates nothing per scan.
  void clear() { stages_.clear(); }
  /// \brief The stages in first-seen order.
  const std::vector<std::pair<std::string, double>>& stages() const { return stages_; }

 private:
  std::vector<std::pair<std::string, double>> stages_;
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_STAGE_TIMES_H
