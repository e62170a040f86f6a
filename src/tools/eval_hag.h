// ground_filter_eval --hag: the heights above ground of a filtered scan against its truth
// (docs/height_above_ground.md, "Accuracy").
#ifndef GROUND_FILTER_TOOLS_EVAL_HAG_H
#define GROUND_FILTER_TOOLS_EVAL_HAG_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "eval/scan_io.h"
#include "ground_filter/cloud_view.h"

namespace ground_filter {
namespace cli {

/// \brief --hag: heights above ground of one file (or pooled).
struct HagResult {
  std::vector<float> error;      // builtin: |height - (z - terrain)| of the finite heights
  std::vector<float> ground;     // heights of truly-ground points (finite)
  std::vector<float> nonground;  // heights of truly-non-ground points (finite)
  std::vector<double> ms;        // build + heights, one per run
  double filter_min = 0.0, filter_med = 0.0;  // the filter's ms on the same scan (min, median)
  std::size_t finite = 0, nan = 0;            // finite points; of them NaN heights
  void add(const HagResult& o) {
    filter_min += o.filter_min;
    filter_med += o.filter_med;
    error.insert(error.end(), o.error.begin(), o.error.end());
    ground.insert(ground.end(), o.ground.begin(), o.ground.end());
    nonground.insert(nonground.end(), o.nonground.begin(), o.nonground.end());
    finite += o.finite;
    nan += o.nan;
  }
};

/// \brief The surface from `labels` (built `repeat` times, timed) and the heights of the scan's
///        points against its exact terrain (builtin: scenes) and its truth labels. `scan_type`:
///        the filter's FilterStats::scan_type ("airborne": no shadow test, as in the nodelets);
///        `threads`: its FilterStats::threads (the surface's threads, as in the nodelets).
HagResult hagOf(const Scan& scan, const CloudView& view, const std::vector<std::uint8_t>& labels,
                const std::string& scan_type, int threads, int repeat);

/// \brief The numbers --hag prints: keys of the JSON, in table order.
std::vector<std::pair<std::string, double>> hagNumbers(HagResult h, double ms_min, double ms_med);

}  // namespace cli
}  // namespace ground_filter

#endif  // GROUND_FILTER_TOOLS_EVAL_HAG_H
