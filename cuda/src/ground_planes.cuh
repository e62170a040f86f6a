// Private: the RANSAC planes on the device (CPU: fitPlaneRansac): one block per
// plane over a work queue, and the grid-wide least-squares refinement of a large cloud plane.
#ifndef GROUND_FILTER_CUDA_SRC_GROUND_PLANES_CUH
#define GROUND_FILTER_CUDA_SRC_GROUND_PLANES_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "ground_common.cuh"

namespace ground_filter {
namespace cuda_impl {

/// RANSAC planes: item 0 the cloud-wide plane (when a tile has < 3 voted points or without
/// local planes; refined grid-wide when large), item 1 + t tile t. `work` and `need_global` are
/// zeroed counters, `partial` holds refinePartialBytes(); `tiles_max` bounds the tile count.
/// With p.sensor_check and `sensor_counts` as launchUnvoteOverhead() left them, no plane passes
/// above the sensor. `sorted_keys`: the tile keys tx << ybits | ty (launchTileKeys()).
void launchPlanes(const float* xyz, const unsigned long long* sorted_keys, int ybits,
                  const unsigned int* tile_begin, const unsigned int* ntiles,
                  const unsigned int* vpos, const unsigned int* vlist, const unsigned int* glist,
                  const unsigned int* gcount, const GroundParamsDev& p, PlaneDev* planes,
                  unsigned int* work, unsigned int* need_global, unsigned int* sensor_counts,
                  double* partial, std::size_t tiles_max, int blocks, cudaStream_t st);
/// Before the tile lists: with p.sensor_check, counts the voted points near the sensor and
/// under it into `sensor_counts` (two zeroed counters, normal::sensorAboveGround()); where no
/// sensor judges the planes, clears the voted flags of the points over other voted ones
/// (normal::overheadPoint(); `column_low` holds og.nx * og.ny ints).
void launchUnvoteOverhead(const float* xyz, std::uint8_t* voted, int n,
                          const normal::OverheadGrid& og, const GroundParamsDev& p,
                          unsigned int* sensor_counts, int* column_low, cudaStream_t st);
/// Bytes of the per-block partial sums of the grid-wide plane refinement.
std::size_t refinePartialBytes();

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GROUND_PLANES_CUH
