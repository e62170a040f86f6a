#ifndef GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H

#include "ground_filter/VoxelGroundFilterConfig.h"
#include "ground_filter/voxel_ground_filter.h"
#include "reconfigurable_filter_nodelet.h"

namespace ground_filter {

/// \brief Nodelet `ground_filter/VoxelGroundFilter`: the voxel method on GroundFilterNodelet,
///        parameters from cfg/VoxelGroundFilter.cfg through dynamic_reconfigure.
class VoxelGroundFilterNodelet
    : public ReconfigurableFilterNodelet<VoxelGroundFilterConfig, VoxelGroundFilterParams,
                                         VoxelGroundFilter> {};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H
