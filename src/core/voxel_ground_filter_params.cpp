#include "ground_filter/voxel_ground_filter_params.h"

#include <stdexcept>
#include <string>

namespace ground_filter {

// The one list of the voxel method's parameters; cfg/VoxelGroundFilter.cfg must agree
// (test_param_tables checks names, ranges, units and defaults).
const ParamTable<VoxelGroundFilterParams>& VoxelGroundFilterParams::table() {
  using P = VoxelGroundFilterParams;
  static const ParamTable<P> rows = {
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
      {"morph_ground", &P::morph_ground, 0, 0, "bool", "airborne: morphological ground surface"},
      {"morph_cell", &P::morph_cell, 0.05, 100.0, "m", "morph: raster cell edge"},
      {"morph_slope", &P::morph_slope, 0.0, 10.0, "", "morph: slope kept by the opening"},
      {"morph_window", &P::morph_window, 0.1, 1000.0, "m", "morph: largest opening radius"},
      {"morph_scale", &P::morph_scale, 0.0, 100.0, "m", "morph: threshold per unit gradient"},
      {"threads", &P::threads, 0, 256, "threads", "worker threads, 0 = all cores"},
  };
  return rows;
}

void VoxelGroundFilterParams::set(const std::string& name, const std::string& value) {
  setParam(table(), "voxel", name, value, this);
}

void VoxelGroundFilterParams::validate() const {
  checkParamRanges(table(), *this);
  if (tile_size < 2.0 * voxel_size) {
    throw std::invalid_argument("parameter 'tile_size' must be at least 2 * voxel_size");
  }
}

std::string VoxelGroundFilterParams::describe() const { return describeParams(table(), *this); }

}  // namespace ground_filter
