#include "eval/metrics.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

namespace ground_filter {

Confusion countConfusion(const std::vector<std::uint8_t>& labels,
                         const std::vector<std::int8_t>& truth) {
  if (labels.size() != truth.size()) {
    throw std::invalid_argument("countConfusion: " + std::to_string(labels.size()) +
                                " labels but " + std::to_string(truth.size()) +
                                " ground-truth values");
  }
  Confusion c;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const bool pred = labels[i] == 1;
    switch (truth[i]) {
      case 1:
        ++(pred ? c.tp : c.fn);
        break;
      case 0:
        ++(pred ? c.fp : c.tn);
        break;
      default:  // ignored
        break;
    }
  }
  return c;
}

namespace {
double ratio(std::uint64_t num, std::uint64_t den) {
  return den == 0 ? std::numeric_limits<double>::quiet_NaN()
                  : static_cast<double>(num) / static_cast<double>(den);
}
}  // namespace

Metrics computeMetrics(const Confusion& c) {
  Metrics m;
  m.accuracy = ratio(c.tp + c.tn, c.total());
  m.precision = ratio(c.tp, c.tp + c.fp);
  m.recall = ratio(c.tp, c.tp + c.fn);
  m.f1 = ratio(2 * c.tp, 2 * c.tp + c.fp + c.fn);
  m.iou = ratio(c.tp, c.tp + c.fp + c.fn);
  return m;
}

void addClassCounts(const std::vector<std::uint8_t>& labels, const std::vector<std::int8_t>& truth,
                    const std::vector<std::uint16_t>& semantic, std::vector<ClassCount>* table) {
  if (labels.size() != truth.size() || labels.size() != semantic.size()) {
    throw std::invalid_argument("addClassCounts: " + std::to_string(labels.size()) + " labels, " +
                                std::to_string(truth.size()) + " ground-truth values, " +
                                std::to_string(semantic.size()) + " classes");
  }
  // Dense per (class, truth) counters: classes are 16-bit ids.
  std::vector<std::uint64_t> points(2u << 16, 0), ground(2u << 16, 0);
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (truth[i] != 0 && truth[i] != 1) continue;
    const std::size_t key = (static_cast<std::size_t>(semantic[i]) << 1) | (truth[i] == 1 ? 1 : 0);
    ++points[key];
    if (labels[i] == 1) ++ground[key];
  }
  for (std::size_t key = 0; key < points.size(); ++key) {
    if (points[key] == 0) continue;
    ClassCount add;
    add.cls = static_cast<std::uint16_t>(key >> 1);
    add.truth = static_cast<std::int8_t>(key & 1);
    add.points = points[key];
    add.labelled_ground = ground[key];
    auto it = std::lower_bound(table->begin(), table->end(), add,
                               [](const ClassCount& a, const ClassCount& b) {
                                 return a.cls != b.cls ? a.cls < b.cls : a.truth < b.truth;
                               });
    if (it != table->end() && it->cls == add.cls && it->truth == add.truth) {
      it->points += add.points;
      it->labelled_ground += add.labelled_ground;
    } else {
      table->insert(it, add);
    }
  }
}

}  // namespace ground_filter
