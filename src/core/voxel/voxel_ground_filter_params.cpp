#include "ground_filter/voxel_ground_filter_params.h"

#include <stdexcept>

#include "airborne/shared_param_rows.h"

namespace ground_filter {

void VoxelGroundFilterParams::validate() const {
  checkSharedParams(*this);
  if (tile_size < 2.0 * voxel_size) {
    throw std::invalid_argument("parameter 'tile_size' must be at least 2 * voxel_size");
  }
  if (veg_min_height > veg_max_height) {
    throw std::invalid_argument("parameter 'veg_min_height' must not exceed veg_max_height");
  }
}

// The rows come from include/ground_filter/params/voxel_params.def, which
// cfg/VoxelGroundFilter.cfg reads too.
#define GF_METHOD_PARAMS VoxelGroundFilterParams
#define GF_METHOD_PARAMS_DEF "ground_filter/params/voxel_params.def"
#include "airborne/method_param_table.inc"

}  // namespace ground_filter
