#include <stdexcept>

#include "ground_filter/ground_filter.h"
#include "ground_filter/normal_ground_filter.h"
#include "ground_filter/paper_normalisation.h"
#include "ground_filter/param_parse.h"
#include "ground_filter/voxel_ground_filter.h"

namespace ground_filter {

std::vector<std::string> groundFilterMethods() { return {"voxel", "normal", "voxel_paper"}; }

std::unique_ptr<GroundFilter> makeGroundFilter(const std::string& method,
                                               const ParamSettings& settings) {
  if (method == "voxel") {
    VoxelGroundFilterParams params;
    for (const auto& kv : settings) params.set(kv.first, kv.second);
    return std::make_unique<VoxelGroundFilter>(params);
  }
  if (method == "normal") {
    NormalGroundFilterParams params;
    for (const auto& kv : settings) params.set(kv.first, kv.second);
    return std::make_unique<NormalGroundFilter>(params);
  }
  if (method == "voxel_paper") {
    // The paper's literal voxel parameters on logistic z-score coordinates (README, "Voxel
    // method", fidelity); settings override them, plus segment_points (65,536) and
    // paper_normalisation (true; false = the same segments in metric coordinates).
    VoxelGroundFilterParams params = paperVoxelParams();
    int segment_points = 65536;
    bool normalise = true;
    for (const auto& kv : settings) {
      if (kv.first == "segment_points") {
        segment_points = parseIntParam(kv.first, kv.second);
      } else if (kv.first == "paper_normalisation") {
        normalise = parseBoolParam(kv.first, kv.second);
      } else {
        params.set(kv.first, kv.second);
      }
    }
    return std::make_unique<PaperNormalisedVoxelFilter>(params, segment_points, normalise);
  }
  std::string known;
  for (const auto& m : groundFilterMethods()) known += (known.empty() ? "" : ", ") + m;
  throw std::invalid_argument("unknown method '" + method + "' (known: " + known + ")");
}

}  // namespace ground_filter
