// Private to the voxel filter: the optional vegetation rule (veg_filter, off by default).
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_VEGETATION_H
#define GROUND_FILTER_SRC_CORE_VOXEL_VEGETATION_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/voxel_ground_filter_params.h"
#include "voxel/classify.h"
#include "voxel/ground_model.h"
#include "voxel/voxel_grid.h"
#include "voxel/worker_pool.h"

namespace ground_filter {
namespace voxel {

/// \brief Step 9 (added, veg_filter): ground points under porous clutter (bush bases,
///        undergrowth) become non-ground. Clutter voxels are those whose centroid lies
///        veg_min_height..veg_max_height above the ground model. A column's ground points at
///        least veg_min_base above the model are relabelled when the (2 veg_radius + 1)^2
///        columns around it hold at least veg_min_points points in clutter voxels, and (with
///        veg_max_density > 0) at most veg_max_density of them per clutter voxel: porous
///        clutter spreads its returns, a solid surface near the sensor (a car's side, a wall)
///        packs them into few voxels.
class VegetationRule {
 public:
  /// \brief Rewrites `cls->ground` (per point, key order; read with cls->plane_height).
  ///        `threads` > 1 splits the columns into ranges of whole rows; the labels do not
  ///        depend on it.
  void run(const VoxelGroundFilterParams& p, const VoxelGrid& g, const GroundModelResult& model,
           int threads, WorkerPool* pool, ClassifyResult* cls);

 private:
  void stats(const VoxelGroundFilterParams& p, const VoxelGrid& g, const float* h0,
             const std::uint8_t* ground, std::size_t c0, std::size_t c1);
  void relabel(const VoxelGroundFilterParams& p, const VoxelGrid& g, const GroundModelResult& model,
               int t, int range, std::uint8_t* ground);

  // Per column (+ an empty sentinel): points << 32 | voxels of its clutter voxels, and whether
  // it holds ground points.
  std::vector<std::uint64_t> clutter_;
  std::vector<std::uint8_t> has_ground_;
  std::vector<std::uint8_t> voxel_has_ground_;      // per voxel
  std::vector<std::uint32_t> row_first_;            // first column of each row x, nx + 1
  std::vector<std::size_t> bounds_;                 // column ranges (whole rows)
  std::vector<std::vector<std::int32_t>> id_rows_;  // per thread: 2 r + 1 rows of column ids
  std::vector<std::vector<std::int64_t>> held_;     // per thread: row x held by each slot
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_VEGETATION_H
