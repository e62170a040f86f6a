#include "voxel_ground_filter_nodelet.h"

#include <pluginlib/class_list_macros.hpp>
#include <sstream>

namespace ground_filter {

VoxelGroundFilterParams voxelParamsFromConfig(const VoxelGroundFilterConfig& config) {
  VoxelGroundFilterParams p;
  p.voxel_size = config.voxel_size;
  p.flatness_threshold = config.flatness_threshold;
  p.min_points_per_voxel = config.min_points_per_voxel;
  p.height_margin = config.height_margin;
  p.seed_window = config.seed_window;
  p.plane_distance = config.plane_distance;
  p.std_filter = config.std_filter;
  p.std_multiplier = config.std_multiplier;
  p.local_planes = config.local_planes;
  p.tile_size = config.tile_size;
  p.max_slope_deg = config.max_slope_deg;
  p.majority_vote = config.majority_vote;
  p.threads = config.threads;
  return p;
}

std::string describeVoxelParams(const VoxelGroundFilterParams& p) {
  std::ostringstream os;
  os << std::boolalpha << "voxel_size=" << p.voxel_size
     << " flatness_threshold=" << p.flatness_threshold
     << " min_points_per_voxel=" << p.min_points_per_voxel << " height_margin=" << p.height_margin
     << " seed_window=" << p.seed_window << " plane_distance=" << p.plane_distance
     << " std_filter=" << p.std_filter << " std_multiplier=" << p.std_multiplier
     << " local_planes=" << p.local_planes << " tile_size=" << p.tile_size
     << " max_slope_deg=" << p.max_slope_deg << " majority_vote=" << p.majority_vote
     << " threads=" << p.threads;
  return os.str();
}

}  // namespace ground_filter

PLUGINLIB_EXPORT_CLASS(ground_filter::VoxelGroundFilterNodelet, nodelet::Nodelet)
