// ground_filter_eval --hag (eval_hag.h).
#include "eval_hag.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "cli_args.h"
#include "ground_filter/height_above_ground.h"

namespace ground_filter {
namespace cli {

namespace {

// The q-quantile (nearest rank, 0..1) of `v`; NaN when empty. Sorts `v`.
double quantile(std::vector<float>* v, double q) {
  if (v->empty()) return NAN;
  const std::size_t k = static_cast<std::size_t>(std::lround(q * (v->size() - 1)));
  std::nth_element(v->begin(), v->begin() + static_cast<std::ptrdiff_t>(k), v->end());
  return (*v)[k];
}

}  // namespace

std::vector<std::pair<std::string, double>> hagNumbers(HagResult h, double ms_min, double ms_med) {
  const double within =
      std::count_if(h.ground.begin(), h.ground.end(), [](float v) { return std::fabs(v) <= 0.1f; });
  return {{"ms_min", ms_min},
          {"ms_median", ms_med},
          {"share_min", h.filter_min > 0.0 ? ms_min / h.filter_min : NAN},
          {"share_median", h.filter_med > 0.0 ? ms_med / h.filter_med : NAN},
          {"nan_share", h.finite ? static_cast<double>(h.nan) / h.finite : NAN},
          {"error_median", quantile(&h.error, 0.5)},
          {"error_p95", quantile(&h.error, 0.95)},
          {"ground_median", quantile(&h.ground, 0.5)},
          {"ground_p5", quantile(&h.ground, 0.05)},
          {"ground_p95", quantile(&h.ground, 0.95)},
          {"ground_within_0_1", h.ground.empty() ? NAN : within / h.ground.size()},
          {"nonground_median", quantile(&h.nonground, 0.5)},
          {"nonground_p5", quantile(&h.nonground, 0.05)},
          {"nonground_p95", quantile(&h.nonground, 0.95)}};
}

HagResult hagOf(const Scan& scan, const CloudView& view, const std::vector<std::uint8_t>& labels,
                const std::string& scan_type, int threads, int repeat) {
  HagResult h;
  GroundSurfaceParams params;
  params.setScanType(scan_type);  // as the nodelets do
  params.threads = threads;
  GroundSurface surface;
  std::vector<float> heights;
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    surface.build(view, labels, params);
    surface.heights(view, &heights);
    h.ms.push_back(msSince(t0));
  }
  // builtin:... (spec checked by loadScan()): exact terrain, but none in a tilted mount's frame.
  const std::string prefix = "builtin:";
  const bool builtin = scan.path.compare(0, prefix.size(), prefix) == 0;
  const SceneParams scene =
      builtin ? parseSceneSpec(scan.path.substr(prefix.size())) : SceneParams();
  const bool terrain = builtin && std::isfinite(sceneGroundHeight(scene, 0.0, 0.0));
  for (std::size_t i = 0; i < view.size(); ++i) {
    float x, y, z;
    if (!view.get(i, &x, &y, &z)) continue;
    ++h.finite;
    const float v = heights[i];
    if (std::isnan(v)) {
      ++h.nan;
      continue;
    }
    if (terrain) h.error.push_back(std::fabs(v - (z - sceneGroundHeight(scene, x, y))));
    if (scan.labelled() && scan.truth[i] == 1) h.ground.push_back(v);
    if (scan.labelled() && scan.truth[i] == 0) h.nonground.push_back(v);
  }
  return h;
}

}  // namespace cli
}  // namespace ground_filter
