#include <stdexcept>

#include "ground_filter/ground_filter.h"
#include "ground_filter/normal_ground_filter.h"
#include "ground_filter/param_parse.h"
#include "ground_filter/voxel_ground_filter.h"
#include "ground_filter/working_volume.h"
#include "voxel/paper_voxel_filter.h"

namespace ground_filter {

std::vector<std::string> groundFilterMethods() { return {"voxel", "normal", "voxel_paper"}; }

std::unique_ptr<GroundFilter> makeGroundFilter(const std::string& method,
                                               const ParamSettings& settings) {
  // max_range, min_range and body_box belong to the working volume around every method, not to a
  // method.
  WorkingVolume volume;
  volume.max_range = 0.0;  // files need not be sensor-centred: hard limit only unless asked
  ParamSettings own;
  for (const auto& kv : settings) {
    if (kv.first == "max_range") {
      volume.max_range = parseDoubleParam(kv.first, kv.second);
    } else if (kv.first == "min_range") {
      volume.min_range = parseDoubleParam(kv.first, kv.second);
    } else if (kv.first == "body_box") {
      volume.body_box = parseBodyBox(kv.first, kv.second);
    } else {
      own.push_back(kv);
    }
  }
  volume.validate();
  std::unique_ptr<GroundFilter> inner;
  if (method == "voxel") {
    VoxelGroundFilterParams params;
    for (const auto& kv : own) params.set(kv.first, kv.second);
    inner = std::make_unique<VoxelGroundFilter>(params);
  } else if (method == "normal") {
    NormalGroundFilterParams params;
    for (const auto& kv : own) params.set(kv.first, kv.second);
    inner = std::make_unique<NormalGroundFilter>(params);
  } else if (method == "voxel_paper") {
    // The paper's literal voxel parameters on logistic z-score coordinates (docs/voxel_method.md,
    // paper fidelity); settings override them and PaperVoxelParams' own rows.
    PaperVoxelParams params;
    for (const auto& kv : own) params.set(kv.first, kv.second);
    inner = std::make_unique<PaperNormalisedVoxelFilter>(params);
  } else {
    std::string known;
    for (const auto& m : groundFilterMethods()) known += (known.empty() ? "" : ", ") + m;
    throw std::invalid_argument("unknown method '" + method + "' (known: " + known + ")");
  }
  return std::make_unique<WorkingVolumeFilter>(std::move(inner), volume);
}

}  // namespace ground_filter
