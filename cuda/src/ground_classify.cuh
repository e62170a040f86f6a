// Private: the distance test on the device (CPU: the plane stage's distance test): each point
// against its tile's plane, with the sparse-tile floor and the optional std band.
#ifndef GROUND_FILTER_CUDA_SRC_GROUND_CLASSIFY_CUH
#define GROUND_FILTER_CUDA_SRC_GROUND_CLASSIFY_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "ground_common.cuh"

namespace ground_filter {
namespace cuda_impl {

/// The raised-tile test after launchPlanes() (CPU: PlaneStage::raisedTiles()): donor[t]
/// (tiles_max ints) = the neighbouring tile whose plane tile t is labelled against, or -1.
/// `sorted_keys`: the tile keys tx << ybits | ty; (min_x, min_y): the tile grid's corner;
/// `tile`: its edge [m].
void launchRaisedTiles(const unsigned long long* sorted_keys, int ybits,
                       const unsigned int* tile_begin, const unsigned int* ntiles,
                       const unsigned int* vpos, const GroundParamsDev& p, const PlaneDev* planes,
                       double min_x, double min_y, double tile, int* donor, std::size_t tiles_max,
                       cudaStream_t st);
/// Distance test per tile (against its donor's plane where launchRaisedTiles() gave one):
/// labels[src[i]] = 1 for ground; ground_count += them. `work` zeroed.
void launchClassify(const float* xyz, const unsigned int* src, const unsigned int* order,
                    const std::uint8_t* voted, const unsigned int* tile_begin,
                    const unsigned int* ntiles, const unsigned int* vpos, const unsigned int* vlist,
                    const GroundParamsDev& p, const PlaneDev* planes, const int* donor,
                    std::uint8_t* labels, unsigned int* ground_count, unsigned int* work,
                    int blocks, cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GROUND_CLASSIFY_CUH
