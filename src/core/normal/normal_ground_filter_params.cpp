#include "ground_filter/normal_ground_filter_params.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "airborne/scan_type.h"
#include "common/shared_param_rows.h"
#include "ground_filter/cuda_knn.h"
#include "ground_filter/neighbor_search.h"
#include "normal/normal_settings.h"

namespace ground_filter {

// The one list of the normal-vector method's parameters; cfg/NormalGroundFilter.cfg must agree
// (test_param_tables checks names, ranges, units and defaults). A parameter the GPU pipeline uses
// goes into gpuNormalParams() below too (and CudaNormalParams); one it cannot honour, into
// gpuSupports().
const ParamTable<NormalGroundFilterParams>& NormalGroundFilterParams::table() {
  using P = NormalGroundFilterParams;
  static const ParamTable<P> rows = withSharedParamRows<P>({
      {"knn_backend", &P::knn_backend, 0, 0, "enum", "kdtree (CPU) | gpu (whole filter on CUDA)"},
      {"k", &P::k, 3, 256, "points", "neighbours per sampled point, itself included"},
      {"sample_stride", &P::sample_stride, 1, 16, "points", "normals on every n-th point"},
      {"cell_size", &P::cell_size, 0.001, 1000.0, "m", "x/y grid cell ordering points"},
      {"min_normal_angle", &P::min_normal_angle, 0.0, 90.0, "deg", "normal window, low end"},
      {"max_normal_angle", &P::max_normal_angle, 90.0, 180.0, "deg", "normal window, high end"},
      {"min_planarity", &P::min_planarity, 0.0, 1.0, "", "candidates at least this planar"},
      {"bayes_vote", &P::bayes_vote, 0, 0, "bool", "naive-Bayes vote over each neighbourhood"},
      {"plane_distance", &P::plane_distance, 0.001, 10.0, "m", "max distance to the plane"},
      {"std_filter", &P::std_filter, 0, 0, "bool", "also the mean +- k std distance band"},
      {"std_multiplier", &P::std_multiplier, 0.1, 10.0, "", "k of that band"},
      {"ransac_iterations", &P::ransac_iterations, 1, 100000, "", "RANSAC hypotheses, at most"},
      {"ransac_seed", &P::ransac_seed, 0, 2147483647, "", "RANSAC seed, 0 = built-in"},
      {"plane_all_points", &P::plane_all_points, 0, 0, "bool", "plane test labels every point"},
      {"local_planes", &P::local_planes, 0, 0, "bool", "one plane per tile"},
      {"tile_size", &P::tile_size, 0.5, 100000.0, "m", "tile edge for local planes"},
      {"floor_share", &P::floor_share, 0.0, 1.0, "", "sparse tile: share on its lowest level"},
      {"floor_max_shift", &P::floor_max_shift, 0.0, 100.0, "m", "sparse tile: plane moved at most"},
      {"local_ground_min", &P::local_ground_min, 0, 256, "points",
       "local ground: ground neighbours needed, 0 = off"},
      {"local_ground_below", &P::local_ground_below, 0.0, 10.0, "m",
       "local ground: under their plane at most"},
      {"local_ground_above", &P::local_ground_above, 0.0, 10.0, "m",
       "local ground: over their plane at most"},
      {"veg_filter", &P::veg_filter, 0, 0, "bool", "ground under porous clutter is non-ground"},
      {"veg_cell", &P::veg_cell, 0.01, 10.0, "m", "veg: column edge and voxel height"},
      {"veg_min_height", &P::veg_min_height, 0.0, 10.0, "m", "veg: clutter band bottom"},
      {"veg_max_height", &P::veg_max_height, 0.0, 10.0, "m", "veg: clutter band top"},
      {"veg_radius", &P::veg_radius, 1, 10, "columns", "veg: window half-width"},
      {"veg_min_points", &P::veg_min_points, 1, 100000, "points", "veg: clutter points needed"},
      {"veg_min_base", &P::veg_min_base, -10.0, 10.0, "m", "veg: relabel from this height"},
      {"veg_max_density", &P::veg_max_density, 0.0, 1000.0, "points", "veg: clutter pts per voxel"},
      {"use_segments", &P::use_segments, 0, 0, "bool", "paper's segments of grid columns"},
      {"segment_points", &P::segment_points, 256, 1 << 26, "points", "points per segment"},
  });
  return rows;
}

void NormalGroundFilterParams::validate() const {
  // The angle window must contain the vertical (90 deg) and reach at most 90 deg from it: the
  // table's ranges say exactly that.
  checkParamRanges(table(), *this);
  validateScanTypeSetting(scan_type);
  if (veg_min_height > veg_max_height) {
    throw std::invalid_argument("parameter 'veg_min_height' must not exceed veg_max_height");
  }
  const auto backends = neighborSearchBackends();
  if (std::find(backends.begin(), backends.end(), knn_backend) == backends.end()) {
    std::string known;
    for (const auto& b : backends) known += (known.empty() ? "" : ", ") + b;
    throw std::invalid_argument("parameter 'knn_backend' = '" + knn_backend +
                                "' is not one of: " + known);
  }
}

namespace normal {

double minAbsNormalZ(const NormalGroundFilterParams& p) {
  const double max_tilt_deg = std::min(90.0 - p.min_normal_angle, p.max_normal_angle - 90.0);
  return std::cos(max_tilt_deg * M_PI / 180.0);
}

bool gpuSupports(const NormalGroundFilterParams& p) {
  // Segments and the bush-base rule run on the host only.
  return !p.use_segments && !p.veg_filter && p.k <= CudaKnn::kMaxK;
}

CudaNormalParams gpuNormalParams(const NormalGroundFilterParams& p) {
  CudaNormalParams g;
  g.k = p.k;
  g.sample_stride = p.sample_stride;
  g.cell_size = p.cell_size;
  g.min_abs_nz = minAbsNormalZ(p);
  g.min_planarity = p.min_planarity;
  g.bayes_vote = p.bayes_vote;
  g.plane_distance = p.plane_distance;
  g.std_filter = p.std_filter;
  g.std_multiplier = p.std_multiplier;
  g.ransac_iterations = p.ransac_iterations;
  g.ransac_seed = p.ransac_seed;
  g.plane_all_points = p.plane_all_points;
  g.local_planes = p.local_planes;
  g.tile_size = p.tile_size;
  g.floor_share = p.floor_share;
  g.floor_max_shift = p.floor_max_shift;
  g.local_ground_min = p.use_segments ? 0 : p.local_ground_min;
  g.local_ground_below = p.local_ground_below;
  g.local_ground_above = p.local_ground_above;
  return g;
}

}  // namespace normal
}  // namespace ground_filter
