#ifndef GROUND_FILTER_SRC_CORE_NORMAL_PLANE_H
#define GROUND_FILTER_SRC_CORE_NORMAL_PLANE_H

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/plane_fit.h"
#include "ground_filter/normal_ground_filter_params.h"
#include "order.h"

namespace ground_filter {
namespace normal {

/// \brief RANSAC plane through the points `idx` of packed `xyz`, its normal within
///        `max_tilt_cos` of vertical (|n_z| >= max_tilt_cos), refined by least squares on its
///        inliers (summed in kPlaneSumLanes lanes, as the GPU sums them); scored on at most 2048
///        evenly strided points; `seed` fixes the samples.
/// \return false when no plane was found (fewer than 3 points or no hypothesis).
bool fitPlaneRansac(const float* xyz, const std::vector<std::uint32_t>& idx, int iterations,
                    double threshold, double max_tilt_cos, std::uint64_t seed,
                    std::vector<std::uint32_t>* eval_scratch, Plane* plane);

/// \brief Stage 5 ("plane"): RANSAC plane per x/y tile (or one for the cloud) through the voted
///        points, then the distance test (and the mean +- std band) that decides ground.
class PlaneStage {
 public:
  /// \brief ground[i] for the `voted.size()` packed points `xyz` inside `extent`; with
  ///        `heights`, also each point's signed height above its plane (normal pointing up;
  ///        NaN where no plane was found).
  void run(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
           const Extent& extent, const NormalGroundFilterParams& p, double min_abs_nz, int threads,
           std::vector<std::uint8_t>* ground, std::vector<float>* heights = nullptr);

 private:
  // The steps of run(), in order.
  void sortIntoTiles(const std::vector<float>& xyz, std::size_t n, const Extent& extent,
                     const NormalGroundFilterParams& p, int threads);
  // The cloud-wide plane when some tile is sparse (or local planes are off); false = none.
  bool fitGlobalPlane(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                      const NormalGroundFilterParams& p, double min_abs_nz, std::uint64_t base_seed,
                      int threads, Plane* global);
  void lowerToFloor(const std::vector<float>& xyz, std::size_t tb, std::size_t te,
                    const NormalGroundFilterParams& p, Plane* plane) const;
  static void distanceBand(const std::vector<float>& xyz, const std::vector<std::uint32_t>& tv,
                           const Plane& plane, const NormalGroundFilterParams& p, double* lo,
                           double* hi);

  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> tile_order_;
  RadixSortScratch sort_scratch_;
  std::vector<std::pair<std::size_t, std::size_t>> tiles_;  // [begin, end) in tile_order_
  std::vector<std::vector<std::uint32_t>> thread_idx_, thread_eval_;
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_PLANE_H
