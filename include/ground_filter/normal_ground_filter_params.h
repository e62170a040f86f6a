#ifndef GROUND_FILTER_NORMAL_GROUND_FILTER_PARAMS_H
#define GROUND_FILTER_NORMAL_GROUND_FILTER_PARAMS_H

#include <string>

#include "ground_filter/morph_ground_params.h"
#include "ground_filter/param_table.h"

namespace ground_filter {

/// \brief Parameters of the normal-vector method (Diaz et al., section 2.3.1). One line per field:
///        meaning [unit] (default; paper value when it differs).
///        The airborne mode's morph_* fields come from MorphGroundParams.
struct NormalGroundFilterParams : TableParams<NormalGroundFilterParams>, MorphGroundParams {
  double cell_size = 0.10;  ///< x/y grid cell ordering points into columns [m] (0.10)
  int k = 40;  ///< neighbours per sampled point, itself included [points] (40; paper 50; GPU <= 64)
  int sample_stride =
      2;  ///< normals and vote on every n-th point in column order [points] (2; paper 1)
  double min_normal_angle = 75.0;  ///< normal-to-horizontal window, low end [deg] (75; paper 80)
  double max_normal_angle =
      105.0;                     ///< normal-to-horizontal window, high end [deg] (105; paper 100)
  double min_planarity = 0.0;    ///< flat: planarity dominant and >= this (see README) [1] (0)
  bool bayes_vote = true;        ///< naive-Bayes vote over each K neighbourhood [bool] (true)
  double plane_distance = 0.15;  ///< max point-to-plane distance of a ground point [m] (paper 0.10)
  bool std_filter = false;       ///< also require mean +- std_multiplier * std of distances [bool]
  double std_multiplier = 1.0;   ///< width of that band in standard deviations [1] (1.0, paper)
  int ransac_iterations = 100;   ///< RANSAC hypotheses per plane, at most [1] (100)
  int ransac_seed = 0;           ///< RANSAC generator seed, 0 = the built-in one [1] (0)
  bool plane_all_points = true;  ///< plane test labels every point, not only voted ones [bool]
  bool local_planes = true;      ///< one plane per tile instead of one for the cloud [bool]
  double tile_size = 4.0;        ///< tile edge for local planes [m] (4.0)
  bool veg_filter = false;       ///< bush-base rule: ground under porous clutter out [bool] (false)
  double veg_cell = 0.10;        ///< bush-base rule: column edge and voxel height [m] (0.10)
  double veg_min_height = 0.2;   ///< veg: clutter band starts this high over the plane [m] (0.2)
  double veg_max_height = 1.2;   ///< veg: clutter band ends this high over the plane [m] (1.2)
  int veg_radius = 1;            ///< veg: window of 2 r + 1 columns a side [columns] (1)
  int veg_min_points = 3;        ///< veg: clutter points in the window [points] (3)
  double veg_min_base = 0.05;    ///< veg: relabel ground points this high or more [m] (0.05)
  double veg_max_density = 2.0;  ///< veg: clutter points per clutter voxel, 0 = any [points] (2.0)
  double floor_share = 0.15;     ///< sparse tile: cloud plane moved to its lowest point when this
                              ///< share of its points is within plane_distance above, 0 = off [1]
  double floor_max_shift = 0.5;  ///< sparse tile: move the cloud-wide plane at most this far [m]
  int local_ground_min = 8;  ///< local ground: a point's list holds this many ground points, whose
                             ///< plane it lies near, to become ground; 0 = off [points] (8)
  double local_ground_below = 0.10;    ///< local ground: under that plane at most [m] (0.10)
  double local_ground_above = 0.05;    ///< local ground: over that plane at most [m] (0.05)
  bool use_segments = false;           ///< paper's segments: no neighbours across borders [bool]
  int segment_points = 65536;          ///< points per segment, at most [points] (65536, paper)
  std::string knn_backend = "kdtree";  ///< neighbour search: kdtree | gpu [enum] (kdtree)
  int threads = 0;                     ///< worker threads, 0 = all cores [threads] (0)

  /// \brief Checks every field's range (and the rules between fields).
  /// \throws std::invalid_argument naming the first bad field, its value and its range.
  void validate() const;
  /// \brief The parameter table (name, member, range, unit) behind set(), validate() and
  ///        describe(); cfg/NormalGroundFilter.cfg must agree with it.
  static const ParamTable<NormalGroundFilterParams>& table();
  /// \brief "normal": the method's name (messages, makeGroundFilter()).
  static const char* method() { return "normal"; }
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_NORMAL_GROUND_FILTER_PARAMS_H
