#ifndef GROUND_FILTER_VOXEL_GROUND_FILTER_PARAMS_H
#define GROUND_FILTER_VOXEL_GROUND_FILTER_PARAMS_H

#include <string>

#include "ground_filter/morph_ground_params.h"
#include "ground_filter/param_table.h"

namespace ground_filter {

/// \brief Parameters of the voxel method (Diaz et al., section 2.3.2). One line per field:
///        meaning [unit] (default; paper value when it differs). docs/voxel_method.md says
///        what each step does with them and gives the measurements behind every default that
///        differs from the paper (paper: plane_distance 0.10, std_filter on, one global plane).
///        The airborne mode's morph_* fields come from MorphGroundParams.
struct VoxelGroundFilterParams : TableParams<VoxelGroundFilterParams>, MorphGroundParams {
  double voxel_size = 0.10;          ///< voxel edge length [m] (0.10, paper)
  double flatness_threshold = 0.08;  ///< flat voxel: max z - min z below this [m] (0.08)
  int min_points_per_voxel = 2;      ///< voxels with fewer points are never flat [points] (2)
  double height_margin = 1.0;        ///< global: cut over mean flat z; local: seed depth [m] (1.0)
  double seed_window = 0.2;          ///< local: seeds at most this above the prediction [m] (0.2)
  double plane_distance = 0.15;      ///< max |distance| of a ground point to its plane [m] (0.15)
  bool std_filter = false;           ///< mean +- k std band test too [bool] (false; paper on)
  double std_multiplier = 1.0;       ///< k of that band, in standard deviations [1] (1.0)
  bool local_planes = true;          ///< grown cell planes, not one plane [bool] (true; paper off)
  double tile_size = 1.0;            ///< cell edge of the local model, >= 2 voxel_size [m] (1.0)
  double max_slope_deg = 30.0;       ///< steeper cell / global planes are rejected [deg] (30)
  bool majority_vote = true;         ///< final 26-neighbourhood vote per voxel [bool] (true)
  bool veg_filter = false;           ///< vegetation rule: ground under clutter out [bool] (false)
  double veg_min_height = 0.2;       ///< veg: clutter band starts this far above ground [m] (0.2)
  double veg_max_height = 1.2;       ///< veg: clutter band ends this far above ground [m] (1.2)
  int veg_radius = 1;                ///< veg: window of 2 r + 1 voxel columns a side [voxels] (1)
  int veg_min_points = 3;            ///< veg: clutter points in the window [points] (3)
  double veg_min_base = 0.05;        ///< veg: relabel ground points this high or more [m] (0.05)
  double veg_max_density = 2.0;      ///< veg: clutter points per voxel, 0 = any [points] (2.0)
  int threads = 1;                   ///< worker threads, 0 = all cores [threads] (1)

  /// \brief Checks every field's range (and the rules between fields).
  /// \throws std::invalid_argument naming the first bad field, its value and its range.
  void validate() const;
  /// \brief The parameter table (name, member, range, unit) behind set(), validate() and
  ///        describe(); cfg/VoxelGroundFilter.cfg must agree with it.
  static const ParamTable<VoxelGroundFilterParams>& table();
  /// \brief "voxel": the method's name (messages, makeGroundFilter()).
  static const char* method() { return "voxel"; }
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_VOXEL_GROUND_FILTER_PARAMS_H
