#include "voxel_ground_filter_nodelet.h"

#include <pluginlib/class_list_macros.hpp>

PLUGINLIB_EXPORT_CLASS(ground_filter::VoxelGroundFilterNodelet, nodelet::Nodelet)
