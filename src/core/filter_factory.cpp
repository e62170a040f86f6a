#include <stdexcept>

#include "ground_filter/ground_filter.h"
#include "ground_filter/normal_ground_filter.h"
#include "ground_filter/param_parse.h"
#include "ground_filter/voxel_ground_filter.h"
#include "ground_filter/working_volume.h"

namespace ground_filter {

std::vector<std::string> groundFilterMethods() { return {"voxel", "normal"}; }

std::unique_ptr<GroundFilter> makeGroundFilter(const std::string& method,
                                               const ParamSettings& settings) {
  // max_range belongs to the working volume around every method, not to a method.
  WorkingVolume volume;
  volume.max_range = 0.0;  // files need not be sensor-centred: hard limit only unless asked
  ParamSettings own;
  for (const auto& kv : settings) {
    if (kv.first == "max_range") {
      volume.max_range = parseDoubleParam(kv.first, kv.second);
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
  } else {
    std::string known;
    for (const auto& m : groundFilterMethods()) known += (known.empty() ? "" : ", ") + m;
    throw std::invalid_argument("unknown method '" + method + "' (known: " + known + ")");
  }
  return std::make_unique<WorkingVolumeFilter>(std::move(inner), volume);
}

}  // namespace ground_filter
