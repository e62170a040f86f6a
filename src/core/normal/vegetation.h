#ifndef GROUND_FILTER_SRC_CORE_NORMAL_VEGETATION_H
#define GROUND_FILTER_SRC_CORE_NORMAL_VEGETATION_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/radix_sort.h"
#include "ground_filter/normal_ground_filter_params.h"
#include "order.h"

namespace ground_filter {
namespace normal {

/// \brief Optional stage after "plane" (veg_filter, off by default): the bush-base rule. Points
///        `veg_min_height`..`veg_max_height` above their tile plane are clutter. A ground point
///        at least `veg_min_base` above its plane becomes non-ground when the
///        (2 `veg_radius` + 1)^2 columns of `veg_cell` around it hold at least `veg_min_points`
///        clutter points and (with `veg_max_density` > 0) at most `veg_max_density` of them per
///        clutter voxel (`veg_cell` cubes): a porous bush, not the solid side of a car or wall.
class VegetationStage {
 public:
  /// \brief Clears ground[i] of the points the rule takes; `height` = each packed point's signed
  ///        height above its tile plane (NaN where no plane). Same result for any `threads`.
  /// \return the number of points relabelled.
  std::size_t run(const std::vector<float>& xyz, const std::vector<float>& height,
                  const Extent& extent, const NormalGroundFilterParams& p, int threads,
                  std::vector<std::uint8_t>* ground);

 private:
  std::vector<std::uint32_t> clutter_;
  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> order_;
  RadixSortScratch scratch_;
  std::vector<std::uint64_t> col_key_;  // sorted clutter columns, (cx << 21) | cy
  std::vector<std::uint32_t> col_points_, col_voxels_;
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_VEGETATION_H
