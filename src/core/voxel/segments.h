// Private to the voxel filter: height filter, region growing, plane of the largest segment.
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_SEGMENTS_H
#define GROUND_FILTER_SRC_CORE_VOXEL_SEGMENTS_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/voxel_ground_filter_params.h"
#include "voxel/voxel_grid.h"

namespace ground_filter {
namespace voxel {

/// \brief Steps 3-5: height filter (global mode), 26-adjacency region growing over the flat
///        voxels of VoxelGrid::flat, the largest segment and its plane.
class Segmenter {
 public:
  /// \brief Runs steps 3-4 (the height filter shortens `g->flat`); returns the segment id of
  ///        the largest segment (most voxels, then most points) or -1 without flat voxels.
  std::int64_t run(const VoxelGroundFilterParams& p, VoxelGrid* g);
  /// \brief Step 5: plane of the largest segment not steeper than max_slope_deg; sets `best` to
  ///        its id. Returns false when there is no flat segment.
  bool globalPlane(const VoxelGroundFilterParams& p, const VoxelGrid& g, std::int64_t* best,
                   HeightPlane* plane);
  /// \brief Segment id (its root) of flat voxel `i` (index into VoxelGrid::flat), after run().
  std::uint32_t segmentOf(std::size_t i) const { return uf_[i]; }

 private:
  std::vector<std::uint32_t> uf_;  // union-find parents, indexed like VoxelGrid::flat
  std::vector<std::uint32_t> seg_voxels_;
  std::vector<std::uint64_t> seg_points_;
  std::vector<std::int32_t> rows_;  // two dense rows of flat ids (x parity)
  std::vector<std::int8_t> rank_;   // globalPlane(): candidate index per segment id, or -1
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_SEGMENTS_H
