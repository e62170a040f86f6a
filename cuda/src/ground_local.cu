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

/// row_of[j] = the KNN row (Morton-sorted position) of sampled point j.
__global__ void rowOfKernel(const float4* __restrict__ pts, int m,
                            unsigned int* __restrict__ row_of) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s < m) row_of[__float_as_int(pts[s].w)] = static_cast<unsigned int>(s);
}

/// The sampled point that ordered point i belongs to: the last j with sidx[j] <= i (-1: none).
__device__ inline int ownerOf(const unsigned int* __restrict__ sidx, int m, int i) {
  if (!sidx) return i;
  int lo = 0, hi = m;  // upper bound of i in sidx[0, m)
  while (lo < hi) {
    const int mid = (lo + hi) >> 1;
    if (sidx[mid] <= static_cast<unsigned int>(i)) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return lo - 1;
}

/// One thread per ordered point (CPU: the inner iteration of LocalGroundStage::run's row loop,
/// the same sums in the same order). A thread per list instead left one thread with every
/// point of a dense column's sample (thousands of no-return points at the origin).
__global__ void localGroundKernel(const float* __restrict__ xyz,
                                  const unsigned int* __restrict__ src,
                                  const unsigned int* __restrict__ row_of,
                                  const std::int32_t* __restrict__ rows, int n, int m,
                                  const unsigned int* __restrict__ sidx, const GroundParamsDev p,
                                  const std::uint8_t* __restrict__ sampled_ground,
                                  std::uint8_t* labels, unsigned int* ground_count) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  unsigned int added = 0;
  const int o = i < n ? ownerOf(sidx, m, i) : -1;
  if (o >= 0 && o < m && !labels[src[i]]) {
    const std::int32_t* row = rows + static_cast<std::size_t>(row_of[o]) * p.k;
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
    if (fit.accepts(p.local_ground_min, p.local_ground_below, p.local_ground_above, p.min_abs_nz)) {
      labels[src[i]] = 1;
      added = 1;
    }
  }
  for (int d = 16; d > 0; d >>= 1) added += __shfl_xor_sync(0xffffffffu, added, d);
  if ((threadIdx.x & 31) == 0 && added) atomicAdd(ground_count, added);
}

}  // namespace

void launchLocalGround(const float* xyz, const unsigned int* src, const float4* pts,
                       const std::int32_t* rows, int n, int m, const unsigned int* sidx,
                       const GroundParamsDev& p, std::uint8_t* sampled_ground, unsigned int* row_of,
                       std::uint8_t* labels, unsigned int* ground_count, cudaStream_t st) {
  if (m <= 0) return;
  sampledGroundKernel<<<blocksFor(m, kThreads), kThreads, 0, st>>>(src, labels, n, m, sidx,
                                                                   sampled_ground);
  GF_CUDA_CHECK_LAUNCH();
  rowOfKernel<<<blocksFor(m, kThreads), kThreads, 0, st>>>(pts, m, row_of);
  GF_CUDA_CHECK_LAUNCH();
  localGroundKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(
      xyz, src, row_of, rows, n, m, sidx, p, sampled_ground, labels, ground_count);
  GF_CUDA_CHECK_LAUNCH();
}

}  // namespace cuda_impl
}  // namespace ground_filter
