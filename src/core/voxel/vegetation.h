// Private to the voxel filter: the optional vegetation rule (veg_filter, off by default).
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_VEGETATION_H
#define GROUND_FILTER_SRC_CORE_VOXEL_VEGETATION_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/voxel_ground_filter.h"
#include "voxel/ground_model.h"
#include "voxel/voxel_grid.h"
#include "voxel/worker_pool.h"

namespace ground_filter {
namespace voxel {

/// \brief Step 9 (added, veg_filter): ground points under porous, volumetric clutter (bush
///        bases, undergrowth) become non-ground. A column's ground points are relabelled when
///        its (2 veg_radius + 1)^2 columns hold at least veg_min_points points
///        veg_min_height..veg_max_height above the ground model, the lowest of them at most
///        veg_max_gap above it (clutter that grows from the ground, not a car body), spread
///        horizontally at least veg_min_spread across their main direction (a volume, not the sheet
///        of a wall or a car's side), with at most veg_max_density of them per voxel they occupy
///        (porous: a solid surface near the sensor packs its returns into few voxels).
class VegetationRule {
 public:
  /// \brief Rewrites `ground` (per point, key order). `threads` > 1 splits the columns into
  ///        ranges of whole rows; the labels do not depend on it.
  void run(const VoxelGroundFilterParams& p, const VoxelGrid& g, const GroundModel& model,
           int threads, WorkerPool* pool, std::vector<std::uint8_t>* ground);

  /// \brief Points 0.2..1.2 m (by default) above the ground model in one column: count, the
  ///        lowest height and moments of x, y relative to the column's centre.
  struct Above {
    float n, nv, hlo, x, y, xx, yy, xy;  // nv: voxels holding such points
  };

 private:
  void stats(const VoxelGroundFilterParams& p, const VoxelGrid& g, const GroundModel& model,
             std::size_t c0, std::size_t c1);
  void relabel(const VoxelGroundFilterParams& p, const VoxelGrid& g, const GroundModel& model,
               int t, int range, std::uint8_t* ground);

  std::vector<Above> above_;  // per column + an empty sentinel
  std::vector<std::size_t> bounds_;
  std::vector<std::uint32_t> row_first_;            // first column of each row x, nx + 1
  std::vector<std::vector<std::int32_t>> id_rows_;  // per thread: 2 r + 1 rows of column ids
  std::vector<std::vector<std::int64_t>> held_;     // per thread: row x held by each slot
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_VEGETATION_H
