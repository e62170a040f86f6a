#include "ground_filter/metrics.h"

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

}  // namespace ground_filter
