// PCA candidates and the naive-Bayes vote (see ground_vote.cuh).
#include <cmath>

#include "cuda_util.cuh"
#include "ground_vote.cuh"
#include "knn_pca.cuh"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

namespace {

constexpr int kThreads = kGroundThreads;

/// CPU: isFlat (planarity of Demantke et al. dominant and >= min_planarity).
__device__ inline bool isFlat(const float eigen[3], double min_planarity) {
  const double s1 = sqrt(static_cast<double>(eigen[2]));
  const double s2 = sqrt(static_cast<double>(eigen[1]));
  const double s3 = sqrt(static_cast<double>(eigen[0]));
  if (!(s1 > 0.0)) return false;
  const double linear = (s1 - s2) / s1, planar = (s2 - s3) / s1, scatter = s3 / s1;
  return planar >= linear && planar >= scatter && planar >= min_planarity;
}

__global__ void pcaCandidatesKernel(const float* __restrict__ xyz, const float4* __restrict__ pts,
                                    const std::int32_t* __restrict__ rows, int n,
                                    const GroundParamsDev p, std::uint8_t* cand,
                                    unsigned int* cand_count) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  bool c = false;
  if (s < n) {
    const float4 q = pts[s];
    float nv[3], ev[3];
    const bool ok = neighborhoodPcaOf(xyz, rows + static_cast<std::size_t>(s) * p.k, p.k, q.x, q.y,
                                      q.z, nv, ev);
    c = ok && isFlat(ev, p.min_planarity) && fabsf(nv[2]) >= p.min_abs_nz;
    cand[__float_as_int(q.w)] = c;
  }
  const int total = __syncthreads_count(c);
  if (threadIdx.x == 0 && total) atomicAdd(cand_count, static_cast<unsigned int>(total));
}

__global__ void voteKernel(const float4* __restrict__ pts, const std::int32_t* __restrict__ rows,
                           int n, const GroundParamsDev p, const std::uint8_t* __restrict__ cand,
                           const unsigned int* __restrict__ cand_count, std::uint8_t* voted) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= n) return;
  const int o = __float_as_int(pts[s].w);
  if (!p.bayes_vote) {
    voted[o] = cand[o];
    return;
  }
  // CPU: ground when U u > V (m - u), U / V the candidates / others of the cloud.
  const double U = static_cast<double>(*cand_count);
  const double V = static_cast<double>(static_cast<unsigned int>(n) - *cand_count);
  const std::int32_t* row = rows + static_cast<std::size_t>(s) * p.k;
  int m = 0, u = 0;
  for (; m < p.k; ++m) {
    const int j = row[m];
    if (j < 0) break;
    u += cand[j];
  }
  voted[o] = U * u > V * (m - u);
}

__global__ void sampleFlagsKernel(const unsigned long long* __restrict__ keys, int n, int stride,
                                  int cap, unsigned int* __restrict__ flags) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i > n) return;
  if (i == n) {
    flags[n] = 0;
    return;
  }
  // The column [a, e) of point i: the run of its key among the sorted keys.
  const unsigned long long key = keys[i];
  int lo = 0, hi = i;
  while (lo < hi) {
    const int mid = (lo + hi) >> 1;
    if (keys[mid] < key) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  const int a = lo;
  lo = i + 1;
  hi = n;
  while (lo < hi) {
    const int mid = (lo + hi) >> 1;
    if (keys[mid] <= key) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  const std::size_t step =
      normal::columnSampleStep(static_cast<std::size_t>(lo - a), static_cast<std::size_t>(stride),
                               static_cast<std::size_t>(cap));
  flags[i] = step == 0 ? (i % stride == 0) : (static_cast<std::size_t>(i - a) % step == 0);
}

__global__ void sampleIndexKernel(const unsigned int* __restrict__ flags,
                                  const unsigned int* __restrict__ pos, int n,
                                  unsigned int* __restrict__ sidx) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i > n) return;
  if (i == n || flags[i]) sidx[pos[i]] = static_cast<unsigned int>(i);
}

__global__ void sampleGatherKernel(const float* __restrict__ xyz,
                                   const unsigned int* __restrict__ sidx, int m,
                                   float* __restrict__ sampled) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= m) return;
  const std::size_t o = 3 * static_cast<std::size_t>(sidx[j]);
  sampled[3 * j] = xyz[o];
  sampled[3 * j + 1] = xyz[o + 1];
  sampled[3 * j + 2] = xyz[o + 2];
}

__global__ void spreadVotesKernel(const std::uint8_t* __restrict__ sampled_voted,
                                  const unsigned int* __restrict__ flags,
                                  const unsigned int* __restrict__ pos, int m, int n,
                                  std::uint8_t* __restrict__ voted) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  // The sampled point at or before i (point 0 is always sampled).
  const int j = static_cast<int>(pos[i] + flags[i]) - 1;
  voted[i] = flags[i] ? sampled_voted[j] : (sampled_voted[j] | sampled_voted[min(j + 1, m - 1)]);
}

}  // namespace

void launchSampleFlags(const unsigned long long* keys, int n, int stride, int cap,
                       unsigned int* flags, cudaStream_t st) {
  sampleFlagsKernel<<<blocksFor(n + 1, kThreads), kThreads, 0, st>>>(keys, n, stride, cap, flags);
  GF_CUDA_CHECK_LAUNCH();
}

void launchSampleIndex(const unsigned int* flags, const unsigned int* pos, int n,
                       unsigned int* sidx, cudaStream_t st) {
  sampleIndexKernel<<<blocksFor(n + 1, kThreads), kThreads, 0, st>>>(flags, pos, n, sidx);
  GF_CUDA_CHECK_LAUNCH();
}

void launchSampleGather(const float* xyz, const unsigned int* sidx, int m, float* sampled,
                        cudaStream_t st) {
  if (m <= 0) return;
  sampleGatherKernel<<<blocksFor(m, kThreads), kThreads, 0, st>>>(xyz, sidx, m, sampled);
  GF_CUDA_CHECK_LAUNCH();
}

void launchSpreadVotes(const std::uint8_t* sampled_voted, const unsigned int* flags,
                       const unsigned int* pos, int m, int n, std::uint8_t* voted,
                       cudaStream_t st) {
  if (n <= 0 || m <= 0) return;
  spreadVotesKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(sampled_voted, flags, pos, m, n,
                                                                 voted);
  GF_CUDA_CHECK_LAUNCH();
}

void launchPcaCandidates(const float* xyz, const float4* pts, const std::int32_t* rows, int n,
                         const GroundParamsDev& p, std::uint8_t* cand, unsigned int* cand_count,
                         cudaStream_t st) {
  pcaCandidatesKernel<<<blocksFor(n, 128), 128, 0, st>>>(xyz, pts, rows, n, p, cand, cand_count);
  GF_CUDA_CHECK_LAUNCH();
}

void launchVote(const float4* pts, const std::int32_t* rows, int n, const GroundParamsDev& p,
                const std::uint8_t* cand, const unsigned int* cand_count, std::uint8_t* voted,
                cudaStream_t st) {
  voteKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(pts, rows, n, p, cand, cand_count, voted);
  GF_CUDA_CHECK_LAUNCH();
}

}  // namespace cuda_impl
}  // namespace ground_filter
