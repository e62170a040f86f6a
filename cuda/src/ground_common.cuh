// Private: what the kernels of the whole normal-vector filter on the device share (the filter
// after the KNN search: ground_columns, ground_vote, ground_tiles, ground_planes, ground_classify).
// Each kernel mirrors a step of NormalGroundFilter::filter() operation by operation in double, so
// the labels equal the CPU's.
#ifndef GROUND_FILTER_CUDA_SRC_GROUND_COMMON_CUH
#define GROUND_FILTER_CUDA_SRC_GROUND_COMMON_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "ground_filter/cuda_normal_pipeline.h"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

/// Settings of the device filter: the host's own struct (ground_filter/cuda_normal_pipeline.h),
/// passed to the kernels by value.
using GroundParamsDev = CudaNormalParams;

/// Plane n . (p - o) + d = 0, as the CPU's Plane.
struct PlaneDev {
  double n[3];
  double d;
  double o[3];
  int valid;
};

/// A cloud-wide plane of more voted points is refined by grid-wide kernels (fixed-order sums:
/// deterministic, may differ from the CPU's lane sums in the last bits); tile planes and smaller
/// cloud-wide planes by their block, in the CPU's order (normal::kPlaneSumLanes).
constexpr unsigned int kBlockRefineMax = 4096;

/// Threads per block of the filter's kernels (the RANSAC planes use their own count).
constexpr int kGroundThreads = 256;

/// Eigen's 3-vector dot order: (a0 b0 + a1 b1) + a2 b2.
__device__ inline double dot3(const double a[3], const double b[3]) {
  return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2];
}

/// Sum of v over the block (all threads get it); `sh` holds one word per warp.
__device__ inline unsigned int blockSum(unsigned int v, unsigned int* sh) {
  for (int o = 16; o > 0; o >>= 1) v += __shfl_xor_sync(0xffffffffu, v, o);
  const int warp = threadIdx.x >> 5, warps = blockDim.x >> 5;
  __syncthreads();
  if ((threadIdx.x & 31) == 0) sh[warp] = v;
  __syncthreads();
  unsigned int s = 0;
  for (int w = 0; w < warps; ++w) s += sh[w];
  return s;
}

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GROUND_COMMON_CUH
