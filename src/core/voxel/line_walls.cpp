// Step 10 of the voxel filter (added): the lowest scan line of a wall or a car (line_walls.h).

#include "voxel/line_walls.h"

#include <cmath>

namespace ground_filter {
namespace voxel {

std::size_t LineWalls::run(const VoxelGrid& g, const float sensor[3], double line_deg,
                           ClassifyResult* cls) const {
  if (!(line_deg > 0.0)) return 0;  // no sparse lines measured: a dense sensor, or none
  const double max_span = WallLines::kLineSpan * line_deg * M_PI / 180.0;
  // The grid's coordinates are relative to its min corner.
  const double sx = static_cast<double>(sensor[0]) - g.min[0];
  const double sy = static_cast<double>(sensor[1]) - g.min[1];
  const double sz = static_cast<double>(sensor[2]) - g.min[2];
  auto elevation = [&](std::size_t v) {
    return std::atan2(g.vz[v] - sz, std::hypot(g.vx[v] - sx, g.vy[v] - sy));
  };
  std::uint8_t* ground = cls->ground.data();
  const float* h0 = cls->plane_height.data();
  const std::uint32_t* vs = g.vstart.data();
  auto holdsGround = [&](std::size_t v) {
    for (std::uint32_t k = vs[v]; k < vs[v + 1]; ++k) {
      if (ground[k]) return true;
    }
    return false;
  };
  std::size_t relabelled = 0;
  for (std::size_t c = 0; c < g.columns(); ++c) {
    // A column's voxels in z order: v and the next one up, u, with an empty voxel or more
    // between them (a surface seen densely has none).
    for (std::size_t v = g.col_first[c], u = v + 1; u < g.col_first[c + 1]; ++v, ++u) {
      if (g.zOf(u) < g.zOf(v) + 2 || g.vz[u] - g.vz[v] > WallLines::kMaxRise) continue;
      if (!holdsGround(v) || holdsGround(u)) continue;
      if (elevation(u) - elevation(v) > max_span) continue;  // lines passed between them
      for (std::uint32_t k = vs[v]; k < vs[v + 1]; ++k) {
        if (ground[k] && g.xyz(k)[2] - h0[v] >= kMinLift) {
          ground[k] = 0;
          ++relabelled;
        }
      }
    }
  }
  return relabelled;
}

}  // namespace voxel
}  // namespace ground_filter
