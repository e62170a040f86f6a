// The local-ground stage (see ground_local.cuh).
#include "cuda_util.cuh"
#include "ground_local.cuh"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

namespace {

constexpr int kThreads = kGroundThreads;

/// Ordered index of sampled point j as an int (the CPU uses the same normal::sampledPosition()).
__device__ inline int sampledAt(const unsigned int* sidx, int j) {
  return static_cast<int>(normal::sampledPosition(sidx, static_cast<std::size_t>(j)));
}

/// CPU: the copy of the sampled points' labels that every decision reads.
__global__ void sampledGroundKernel(const unsigned int* __restrict__ src,
                                    const std::uint8_t* __restrict__ labels, int n, int m,
                                    const unsigned int* __restrict__ sidx,
                                    std::uint8_t* __restrict__ sampled_ground) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= m) return;
  sampled_ground[j] = labels[src[min(sampledAt(sidx, j), n - 1)]];
}

/// One thread per list (CPU: one iteration of LocalGroundStage::run's row loop, same sums in the
/// same order).
__global__ void localGroundKernel(const float* __restrict__ xyz,
                                  const unsigned int* __restrict__ src,
                                  const float4* __restrict__ pts,
                                  const std::int32_t* __restrict__ rows, int n, int m,
                                  const unsigned int* __restrict__ sidx, const GroundParamsDev p,
                                  const std::uint8_t* __restrict__ sampled_ground,
                                  std::uint8_t* labels, unsigned int* ground_count) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  unsigned int added = 0;
  if (s < m) {
    const int o = __float_as_int(pts[s].w);
    const std::int32_t* row = rows + static_cast<std::size_t>(s) * p.k;
    const int end = min(sampledAt(sidx, o + 1), n);
    for (int i = sampledAt(sidx, o); i < end; ++i) {
      const unsigned int out = src[i];
      if (labels[out]) continue;
      const float* q = xyz + 3 * static_cast<std::size_t>(i);
      normal::LocalGroundFit fit;
      for (int e = 0; e < p.k && row[e] >= 0; ++e) {
        const int j = row[e];
        if (!sampled_ground[j]) continue;
        const float* g = xyz + 3 * static_cast<std::size_t>(sampledAt(sidx, j));
        fit.add(static_cast<double>(g[0]) - static_cast<double>(q[0]),
                static_cast<double>(g[1]) - static_cast<double>(q[1]),
                static_cast<double>(g[2]) - static_cast<double>(q[2]));
      }
      if (fit.accepts(p.local_ground_min, p.local_ground_below, p.local_ground_above,
                      p.min_abs_nz)) {
        labels[out] = 1;
        ++added;
      }
    }
  }
  for (int d = 16; d > 0; d >>= 1) added += __shfl_xor_sync(0xffffffffu, added, d);
  if ((threadIdx.x & 31) == 0 && added) atomicAdd(ground_count, added);
}

}  // namespace

void launchLocalGround(const float* xyz, const unsigned int* src, const float4* pts,
                       const std::int32_t* rows, int n, int m, const unsigned int* sidx,
                       const GroundParamsDev& p, std::uint8_t* sampled_ground, std::uint8_t* labels,
                       unsigned int* ground_count, cudaStream_t st) {
  if (m <= 0) return;
  sampledGroundKernel<<<blocksFor(m, kThreads), kThreads, 0, st>>>(src, labels, n, m, sidx,
                                                                   sampled_ground);
  GF_CUDA_CHECK_LAUNCH();
  localGroundKernel<<<blocksFor(m, kThreads), kThreads, 0, st>>>(
      xyz, src, pts, rows, n, m, sidx, p, sampled_ground, labels, ground_count);
  GF_CUDA_CHECK_LAUNCH();
}

}  // namespace cuda_impl
}  // namespace ground_filter
