#ifndef GROUND_FILTER_SRC_CORE_NORMAL_LOCAL_GROUND_H
#define GROUND_FILTER_SRC_CORE_NORMAL_LOCAL_GROUND_H

#include <cstddef>
#include <cstdint>
#include <vector>

namespace ground_filter {
namespace normal {

/// \brief Stage 5a ("local_ground", local_ground_min > 0): a non-ground point becomes ground when
///        the neighbour list of its sampled point (the one at or before it in column order) holds
///        at least `min_ground` ground points of the plane stage and the point lies at most
///        `max_below` under or `max_above` over their least-squares plane, whose normal is within
///        the plane window (LocalGroundFit, shared with the GPU). One pass over the plane stage's
///        labels, so the result does not depend on the order: a verge that bends away from its
///        tile's plane inside the tile is followed; a bush whose neighbours are mostly not ground,
///        or that stands above their plane, is not (a point under the ground around it cannot stand
///        on it, one over it can be an object's base: hence the narrower band above).
class LocalGroundStage {
 public:
  /// \brief `xyz`: the n = ground->size() ordered points, point `sampled[j]` being sampled
  ///        point j (`sampled`: m + 1 positions, the last n, SampleStage::sampledIndex(); null:
  ///        every point sampled); `rows`: `m` neighbour lists of `k` sampled-point indices (-1 =
  ///        none), row r belonging to sampled point `points[r]` (r when `points` is null);
  ///        `ground`: the plane stage's labels, updated.
  /// \return the points relabelled ground.
  std::size_t run(const std::vector<float>& xyz, const std::int32_t* rows,
                  const std::uint32_t* points, std::size_t m, int k, const std::uint32_t* sampled,
                  int min_ground, double max_below, double max_above, double min_abs_nz,
                  int threads, std::vector<std::uint8_t>* ground);

 private:
  std::vector<std::uint8_t> sampled_ground_;
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_LOCAL_GROUND_H
