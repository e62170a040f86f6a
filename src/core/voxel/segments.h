// Private to the voxel filter: height filter, region growing, plane of the largest segment.
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_SEGMENTS_H
#define GROUND_FILTER_SRC_CORE_VOXEL_SEGMENTS_H

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "ground_filter/voxel_ground_filter_params.h"
#include "voxel/voxel_grid.h"

namespace ground_filter {
namespace voxel {

/// \brief What Segmenter writes: the segment of every flat voxel, the chosen segment and its
///        plane (the ground model's start and, in global mode, the ground model itself).
struct SegmentResult {
  /// \brief Per flat voxel (index into VoxelGrid::flat): its segment id (the root of its
  ///        union-find set; the parents while run() joins).
  std::vector<std::uint32_t> segment;
  /// \brief Segment id of the largest segment (run()), then of the one whose plane
  ///        globalPlane() took; -1 without flat voxels.
  std::int64_t best = -1;
  /// \brief globalPlane(): whether `plane` holds a plane (false: no flat segment).
  bool have_plane = false;
  /// \brief globalPlane(): plane of segment `best`.
  HeightPlane plane;
};

/// \brief Steps 3-5: height filter (global mode), 26-adjacency region growing over the flat
///        voxels of VoxelGrid::flat, the largest segment and its plane.
class Segmenter {
 public:
  /// \brief Runs steps 3-4 (the height filter shortens `g->flat`): writes the segment of every
  ///        flat voxel and the largest segment (most voxels, then most points) to `out`.
  void run(const VoxelGroundFilterParams& p, VoxelGrid* g, SegmentResult* out);
  /// \brief Step 5: plane of the largest segment of `seg` (run()'s result of this scan) not
  ///        steeper than max_slope_deg; sets `seg->best`, `seg->plane` and `seg->have_plane`
  ///        (false when there is no flat segment). With `sensor` (x y z in the input frame: a
  ///        sensor at the origin, not a registered cloud) the largest such segment whose plane
  ///        passes below the sensor and whose points lie below it (their mean at most 0.5 m
  ///        above it) is taken where one of the largest does, else the largest whose plane
  ///        passes below it: the ground under a ground-level sensor lies below it, a crown's
  ///        underside above it. Of those, the ones not above the ground that the sensor's
  ///        steepest lines of sight meet come first (a crown or a roof below a high sensor).
  void globalPlane(const VoxelGroundFilterParams& p, const VoxelGrid& g, const float* sensor,
                   SegmentResult* seg);

 private:
  // globalPlane(): hist_ (heights in bins of `bin`) and steep_ of the flat voxels within
  // kSupportRadius of the sensor.
  void scanNearSensor(const VoxelGrid& g, const float* sensor, double bin);

  // Scratch; seg_voxels_ and seg_points_ carry run()'s segment sizes to globalPlane().
  std::vector<std::uint32_t> seg_voxels_;
  std::vector<std::uint64_t> seg_points_;
  std::vector<std::int32_t> rows_;   // two dense rows of flat ids (x parity)
  std::vector<std::uint32_t> hist_;  // globalPlane(): flat voxels near the sensor per height bin
  // globalPlane(): per flat voxel near the sensor, its line of sight's slope and its height
  std::vector<std::pair<float, float>> steep_;
  std::vector<std::int8_t> rank_;  // globalPlane(): candidate index per segment id, or -1
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_SEGMENTS_H
