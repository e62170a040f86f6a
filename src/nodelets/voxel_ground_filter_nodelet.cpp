#include "voxel_ground_filter_nodelet.h"

#include <pluginlib/class_list_macros.hpp>

#include "params_from_config.h"

namespace ground_filter {

VoxelGroundFilterParams voxelParamsFromConfig(const VoxelGroundFilterConfig& config) {
  return paramsFromConfigTable<VoxelGroundFilterParams>(config);
}

std::string describeVoxelParams(const VoxelGroundFilterParams& p) { return p.describe(); }

}  // namespace ground_filter

PLUGINLIB_EXPORT_CLASS(ground_filter::VoxelGroundFilterNodelet, nodelet::Nodelet)
