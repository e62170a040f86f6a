// Private to the voxel filter: the lowest scan line of a wall or a car seen by a sparse spinning
// sensor (step 10).
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_LINE_WALLS_H
#define GROUND_FILTER_SRC_CORE_VOXEL_LINE_WALLS_H

#include <cstddef>
#include <cstdint>

#include "common/scan_lines.h"
#include "voxel/classify.h"
#include "voxel/voxel_grid.h"

namespace ground_filter {
namespace voxel {

/// \brief Step 10 (added): a sparse spinning sensor's lowest scan line on a wall or a car's side
///        lies up to one line spacing above the ground and looks like a ring on the ground; the
///        next line up hits the same surface straight above it. Ground points not below their
///        cell plane (kMinLift) become non-ground where the next voxel up their column lies an
///        empty voxel or more higher, holds only non-ground points, and is seen from the sensor
///        less than WallLines::kLineSpan lines higher (at most WallLines::kMaxRise): no line
///        passed between them, so the two lie on one upright surface. Ground under an overhang
///        (a bush, a tree) mostly has lines passing over it first and stays; ground right at the
///        foot of a car or a wall, hit by the line below the one on the object, stays where it
///        lies below the plane.
class LineWalls {
 public:
  /// \brief Least height of a relabelled point above its cell plane [m]: a line on a wall lies
  ///        above the ground, ground at a wall's foot scatters about the plane (about half of
  ///        it stays).
  static constexpr double kMinLift = 0.0;

  /// \brief Rewrites `cls->ground` (per point, key order; read with cls->plane_height), seen
  ///        from `sensor` (x, y, z in the grid's frame) whose scan lines lie `line_deg` apart.
  ///        Returns the points relabelled.
  std::size_t run(const VoxelGrid& g, const float sensor[3], double line_deg,
                  ClassifyResult* cls) const;
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_LINE_WALLS_H
