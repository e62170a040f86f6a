#ifndef GROUND_FILTER_VOXEL_GROUND_FILTER_PARAMS_H
#define GROUND_FILTER_VOXEL_GROUND_FILTER_PARAMS_H

#include <string>

#include "ground_filter/morph_ground_params.h"
#include "ground_filter/param_table.h"
#include "ground_filter/params/param_def.h"

namespace ground_filter {

/// \brief Parameters of the voxel method (Diaz et al., section 2.3.2): name, type, default,
///        range, unit, paper value and meaning of each are in
///        include/ground_filter/params/voxel_params.def (docs/parameters.md lists them).
///        docs/voxel_method.md says what each step does with them and gives the measurements
///        behind every default that differs from the paper (paper: plane_distance 0.10,
///        std_filter on, one global plane). The airborne mode's morph_* and scan_type fields come
///        from MorphGroundParams.
struct VoxelGroundFilterParams : TableParams<VoxelGroundFilterParams>, MorphGroundParams {
#define GF_PARAM GF_PARAM_MEMBER
#include "ground_filter/params/voxel_params.def"
#undef GF_PARAM

  // validate(), table() (cfg/VoxelGroundFilter.cfg must agree with it), method().
  GF_TABLE_PARAMS_MEMBERS(VoxelGroundFilterParams, "voxel")
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_VOXEL_GROUND_FILTER_PARAMS_H
