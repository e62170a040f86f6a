// Private: the local-ground stage on the device (CPU: normal/local_ground.cpp): a non-ground
// point becomes ground when its sampled point's neighbour list holds enough ground points and it
// lies near their least-squares plane (normal::LocalGroundFit, shared with the CPU).
#ifndef GROUND_FILTER_CUDA_SRC_GROUND_LOCAL_CUH
#define GROUND_FILTER_CUDA_SRC_GROUND_LOCAL_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "ground_common.cuh"

namespace ground_filter {
namespace cuda_impl {

/// After the distance test: `xyz`/`src` the n ordered points, `pts`/`rows` the KNN's m sampled
/// points (pts[s].w = sampled index) and their lists of k entries, sampled point j being ordered
/// point sidx[j] (m + 1 entries, the last n; null: every point sampled); labels[src[i]] set to 1
/// for the points it adds, ground_count += them. Scratch: `sampled_ground` m bytes, `row_of` m
/// entries.
void launchLocalGround(const float* xyz, const unsigned int* src, const float4* pts,
                       const std::int32_t* rows, int n, int m, const unsigned int* sidx,
                       const GroundParamsDev& p, std::uint8_t* sampled_ground, unsigned int* row_of,
                       std::uint8_t* labels, unsigned int* ground_count, cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GROUND_LOCAL_CUH
