#ifndef GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H

#include <string>

#include "ground_filter/VoxelGroundFilterConfig.h"
#include "ground_filter/voxel_ground_filter.h"
#include "ground_filter_nodelet.h"

namespace ground_filter {

/// \brief Maps every dynamic_reconfigure field onto VoxelGroundFilterParams (no validation).
VoxelGroundFilterParams voxelParamsFromConfig(const VoxelGroundFilterConfig& config);

/// \brief One line "name=value ..." of all voxel parameters, for logs.
std::string describeVoxelParams(const VoxelGroundFilterParams& params);

/// \brief Nodelet `ground_filter/VoxelGroundFilter`: the voxel method on GroundFilterNodelet,
///        parameters from cfg/VoxelGroundFilter.cfg through dynamic_reconfigure.
class VoxelGroundFilterNodelet
    : public ReconfigurableFilterNodelet<VoxelGroundFilterConfig, VoxelGroundFilterParams,
                                         VoxelGroundFilter> {
 protected:
  std::string methodName() const override { return "voxel"; }
  VoxelGroundFilterParams paramsFromConfig(const VoxelGroundFilterConfig& config) const override {
    return voxelParamsFromConfig(config);
  }
  std::string describeParams(const VoxelGroundFilterParams& params) const override {
    return describeVoxelParams(params);
  }
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H
