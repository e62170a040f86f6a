#include "ground_filter/voxel_ground_filter_params.h"

#include <stdexcept>
#include <string>

#include "airborne/scan_type.h"
#include "common/shared_param_rows.h"

namespace ground_filter {

// The one list of the voxel method's parameters; cfg/VoxelGroundFilter.cfg must agree
// (test_param_tables checks names, ranges, units and defaults).
const ParamTable<VoxelGroundFilterParams>& VoxelGroundFilterParams::table() {
  using P = VoxelGroundFilterParams;
  static const ParamTable<P> rows = withSharedParamRows<P>({
      {"voxel_size", &P::voxel_size, 0.005, 10.0, "m", "voxel edge length"},
      {"flatness_threshold", &P::flatness_threshold, 0.0001, 10.0, "m", "flat: max z - min z"},
      {"min_points_per_voxel", &P::min_points_per_voxel, 1, 1000, "points", "never flat below"},
      {"height_margin", &P::height_margin, 0.01, 100.0, "m", "height cut / seed depth"},
      {"seed_window", &P::seed_window, 0.01, 100.0, "m", "seeds at most this above prediction"},
      {"plane_distance", &P::plane_distance, 0.001, 10.0, "m", "max distance to the plane"},
      {"std_filter", &P::std_filter, 0, 0, "bool", "also the mean +- k std distance band"},
      {"std_multiplier", &P::std_multiplier, 0.1, 10.0, "", "k of that band"},
      {"local_planes", &P::local_planes, 0, 0, "bool", "grown cell planes, not one plane"},
      {"tile_size", &P::tile_size, 0.01, 1000.0, "m", "cell edge, >= 2 voxel_size"},
      {"max_slope_deg", &P::max_slope_deg, 0.0, 89.0, "deg", "steeper planes are rejected"},
      {"majority_vote", &P::majority_vote, 0, 0, "bool", "final 26-neighbourhood vote"},
      {"veg_filter", &P::veg_filter, 0, 0, "bool", "ground under porous clutter is non-ground"},
      {"veg_min_height", &P::veg_min_height, 0.0, 10.0, "m", "veg: clutter band bottom"},
      {"veg_max_height", &P::veg_max_height, 0.0, 10.0, "m", "veg: clutter band top"},
      {"veg_radius", &P::veg_radius, 1, 10, "voxels", "veg: window half-width"},
      {"veg_min_points", &P::veg_min_points, 1, 100000, "points", "veg: clutter points needed"},
      {"veg_min_base", &P::veg_min_base, -10.0, 10.0, "m", "veg: relabel from this height"},
      {"veg_max_density", &P::veg_max_density, 0.0, 1000.0, "points", "veg: clutter pts per voxel"},
  });
  return rows;
}

void VoxelGroundFilterParams::validate() const {
  checkParamRanges(table(), *this);
  validateScanTypeSetting(scan_type);
  if (tile_size < 2.0 * voxel_size) {
    throw std::invalid_argument("parameter 'tile_size' must be at least 2 * voxel_size");
  }
  if (veg_min_height > veg_max_height) {
    throw std::invalid_argument("parameter 'veg_min_height' must not exceed veg_max_height");
  }
}

}  // namespace ground_filter
