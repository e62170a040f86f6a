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
///        evenly strided points; `seed` fixes the samples. With `sensor` (x, y, z of a sensor at
///        a scan's origin; null: none), hypotheses that pass above it are skipped and a refit
///        that would is not taken (planeAboveSensor()).
/// \return false when no plane was found (fewer than 3 points or no hypothesis).
bool fitPlaneRansac(const float* xyz, const std::vector<std::uint32_t>& idx, int iterations,
                    double threshold, double max_tilt_cos, std::uint64_t seed,
                    std::vector<std::uint32_t>* eval_scratch, Plane* plane,
                    const double* sensor = nullptr);

/// \brief Stage 5 ("plane"): RANSAC plane per x/y tile (or one for the cloud) through the voted
///        points, then the distance test (and the mean +- std band) that decides ground.
class PlaneStage {
 public:
  /// \brief ground[i] for the `voted.size()` packed points `xyz` inside `extent`; with
  ///        `heights`, also each point's signed height above its plane (normal pointing up;
  ///        NaN where no plane was found). `sensor`: the sensor's x, y, z when the scan has
  ///        one at its origin (no plane may pass above it; the cloud-wide plane is then always
  ///        fitted, for the tiles whose voted points hold none below it), else null: then
  ///        the voted points 1 m or more over the lowest voted point of their column
  ///        (overheadPoint()) are left out of the planes first.
  void run(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
           const Extent& extent, const NormalGroundFilterParams& p, double min_abs_nz, int threads,
           std::vector<std::uint8_t>* ground, std::vector<float>* heights = nullptr,
           const double* sensor = nullptr);

 private:
  // Clears the voted flags of the points over other voted ones (overheadPoint()).
  void unvoteOverhead(const std::vector<float>& xyz, const Extent& extent,
                      std::vector<std::uint8_t>* voted);
  // The tile planes and the distance test of run(), after its sensor decision; `floor_from`:
  // run()'s sensor before that decision (lowerToFloor()).
  void runTiles(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                const NormalGroundFilterParams& p, double min_abs_nz, int threads,
                std::vector<std::uint8_t>* ground, std::vector<float>* heights,
                const double* sensor, const double* floor_from);
  // The steps of run(), in order.
  void sortIntoTiles(const std::vector<float>& xyz, std::size_t n, const Extent& extent,
                     const NormalGroundFilterParams& p, int threads);
  // Whether the cloud-wide plane is needed before the tiles: some tile is sparse (or local
  // planes are off).
  bool needGlobalPlane(const std::vector<std::uint8_t>& voted,
                       const NormalGroundFilterParams& p) const;
  // The cloud-wide plane through every voted point; false = none.
  bool fitGlobalPlane(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                      const NormalGroundFilterParams& p, double min_abs_nz, std::uint64_t base_seed,
                      const double* sensor, Plane* global);
  // The raised-tile test (normal::raisedTileMedian()): raised_[t] = the neighbour whose plane
  // tile t is labelled against, where its own stands more than kRaisedTileStep above theirs.
  void raisedTiles();
  // The voted points of tile t into *tv.
  void votedOfTile(const std::vector<std::uint8_t>& voted, std::size_t t,
                   std::vector<std::uint32_t>* tv) const;
  // The distance test of tile t (tile_voted_[t] voted points) against `plane`.
  void labelTile(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                 std::size_t t, Plane plane, const NormalGroundFilterParams& p,
                 const double* floor_from, std::vector<std::uint8_t>* ground,
                 std::vector<float>* heights) const;
  // The sparse-tile floor: `plane` moved to the tile's lowest level where that holds enough of
  // it (floorReach(), floorShare(); `sensor` null: the reach is floor_max_shift).
  void lowerToFloor(const std::vector<float>& xyz, std::size_t tb, std::size_t te,
                    const NormalGroundFilterParams& p, const double* sensor, Plane* plane) const;
  // The band of tile t's voted points' distances to `plane` (std_filter).
  void distanceBand(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                    std::size_t t, const Plane& plane, const NormalGroundFilterParams& p,
                    double* lo, double* hi) const;

  /// (tx << 32) | ty of a sort key tx << y_bits_ | ty (the key the RANSAC seeds are drawn from).
  std::uint64_t tileKey(std::uint64_t k) const {
    return ((k >> y_bits_) << 32) | (k & ((std::uint64_t{1} << y_bits_) - 1));
  }

  std::vector<std::uint64_t> keys_;
  int y_bits_ = 0;  // bits of the largest ty (sortIntoTiles())
  std::vector<std::uint32_t> tile_order_;
  RadixSortScratch sort_scratch_;
  std::vector<std::pair<std::size_t, std::size_t>> tiles_;  // [begin, end) in tile_order_
  std::vector<std::vector<std::uint32_t>> thread_idx_, thread_eval_;
  std::vector<std::uint32_t> global_idx_, global_eval_;  // the cloud-wide fit beside the tiles'
  std::vector<std::uint8_t> wants_global_;  // per tile: labelled with the cloud-wide plane
  std::vector<std::uint8_t> deferred_;      // per tile: labelled with the late cloud-wide plane
  // Per tile: the plane it is labelled against, and where that came from.
  enum TilePlane : std::uint8_t { kNoPlane, kOwnPlane, kCloudPlane };
  std::vector<Plane> tile_plane_;
  std::vector<std::uint8_t> tile_kind_;
  std::vector<std::uint32_t> tile_voted_;  // per tile: its voted points (the fit loop counts)
  std::vector<std::int64_t> raised_;       // per tile: the neighbour whose plane it takes, or -1
  double tile_size_ = 1.0, tile_min_x_ = 0.0, tile_min_y_ = 0.0;  // the tile grid
  std::vector<std::uint8_t> unroofed_;  // voted less the overhead points (no sensor only)
  std::vector<float> column_low_;       // lowest voted z per overhead-test column
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_PLANE_H
