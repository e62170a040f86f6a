#include <stdexcept>

#include "ground_filter/ground_filter.h"
#include "ground_filter/normal_ground_filter.h"
#include "ground_filter/voxel_ground_filter.h"

namespace ground_filter {

std::vector<std::string> groundFilterMethods() { return {"voxel", "normal"}; }

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
  std::string known;
  for (const auto& m : groundFilterMethods()) known += (known.empty() ? "" : ", ") + m;
  throw std::invalid_argument("unknown method '" + method + "' (known: " + known + ")");
}

}  // namespace ground_filter
