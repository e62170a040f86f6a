#ifndef GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H

#include <dynamic_reconfigure/server.h>

#include <memory>
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
class VoxelGroundFilterNodelet : public GroundFilterNodelet {
 public:
  VoxelGroundFilterNodelet();
  ~VoxelGroundFilterNodelet() override;

 protected:
  void onInitFilter() override;
  std::string methodName() const override { return "voxel"; }

 private:
  void reconfigure(VoxelGroundFilterConfig& config, uint32_t level);

  std::unique_ptr<dynamic_reconfigure::Server<VoxelGroundFilterConfig>> server_;
  VoxelGroundFilterConfig last_good_;  // reported back when a new set is refused
  bool have_good_ = false;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_VOXEL_GROUND_FILTER_NODELET_H
