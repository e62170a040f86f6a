#include "ground_filter/voxel_ground_filter_params.h"

#include <stdexcept>
#include <string>

#include "airborne/scan_type.h"
#include "common/shared_param_rows.h"

namespace ground_filter {

// The rows come from include/ground_filter/params/voxel_params.def, which
// cfg/VoxelGroundFilter.cfg reads too.
const ParamTable<VoxelGroundFilterParams>& VoxelGroundFilterParams::table() {
  using P = VoxelGroundFilterParams;
  static const ParamTable<P> rows = withSharedParamRows<P>({
#define GF_PARAM GF_PARAM_ROW
#include "ground_filter/params/voxel_params.def"
#undef GF_PARAM
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
