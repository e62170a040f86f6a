// The whole normal-vector filter's kernels after the KNN search (see ground_kernels.cuh).
#include <cmath>

#include "cuda_util.cuh"
#include "ground_kernels.cuh"
#include "knn_grid.cuh"
#include "knn_pca.cuh"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

namespace {

constexpr int kThreads = 256;
constexpr int kPlaneThreads = 128;
constexpr int kChunk = 256;               // points staged per step of a serial least-squares sum
constexpr int kPlaneNeedsRefinement = 2;  // PlaneDev::valid of a hypothesis awaiting refinement
constexpr int kRefineBlocks = 264;        // blocks of the grid-wide refinement

using normal::cellIndex;
using normal::columnKey;
using normal::kMinTilePoints;
using normal::SplitMix64;
constexpr unsigned int kEvalMax = normal::kRansacEvalPoints;

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

// ------------------------------------------------------------------ compaction, column order

__global__ void finiteFlagsKernel(const float* __restrict__ in, int n, unsigned int* flags) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i > n) return;
  if (i == n) {
    flags[n] = 0;
    return;
  }
  const float x = in[3 * static_cast<std::size_t>(i)], y = in[3 * static_cast<std::size_t>(i) + 1],
              z = in[3 * static_cast<std::size_t>(i) + 2];
  flags[i] = isfinite(x) && isfinite(y) && isfinite(z);
}

__global__ void initBounds2Kernel(int* b) {
  if (threadIdx.x < 2) b[threadIdx.x] = 0x7fffffff;
  if (threadIdx.x >= 2 && threadIdx.x < 4) b[threadIdx.x] = static_cast<int>(0x80000000u);
}

__global__ void compactKernel(const float* __restrict__ in, const unsigned int* __restrict__ flags,
                              const unsigned int* __restrict__ pos, int n, float* raw_xyz,
                              unsigned int* raw_src, int* bounds) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  float mnx = INFINITY, mny = INFINITY, mxx = -INFINITY, mxy = -INFINITY;
  if (i < n && flags[i]) {
    const std::size_t s = 3 * static_cast<std::size_t>(i), d = 3 * static_cast<std::size_t>(pos[i]);
    const float x = in[s], y = in[s + 1], z = in[s + 2];
    raw_xyz[d] = x;
    raw_xyz[d + 1] = y;
    raw_xyz[d + 2] = z;
    raw_src[pos[i]] = static_cast<unsigned int>(i);
    mnx = mxx = x;
    mny = mxy = y;
  }
  for (int o = 16; o > 0; o >>= 1) {
    mnx = fminf(mnx, __shfl_xor_sync(0xffffffffu, mnx, o));
    mny = fminf(mny, __shfl_xor_sync(0xffffffffu, mny, o));
    mxx = fmaxf(mxx, __shfl_xor_sync(0xffffffffu, mxx, o));
    mxy = fmaxf(mxy, __shfl_xor_sync(0xffffffffu, mxy, o));
  }
  if ((threadIdx.x & 31) == 0 && mnx <= mxx) {
    atomicMin(&bounds[0], floatToOrdered(mnx));
    atomicMin(&bounds[1], floatToOrdered(mny));
    atomicMax(&bounds[2], floatToOrdered(mxx));
    atomicMax(&bounds[3], floatToOrdered(mxy));
  }
}

__global__ void columnKeysKernel(const float* __restrict__ xyz, int n, double min_x, double min_y,
                                 double inv_cell, unsigned long long* keys, unsigned int* vals) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const std::size_t s = 3 * static_cast<std::size_t>(i);
  const std::uint32_t cx = cellIndex(xyz[s], min_x, inv_cell);
  const std::uint32_t cy = cellIndex(xyz[s + 1], min_y, inv_cell);
  keys[i] = columnKey(cx, cy);
  vals[i] = static_cast<unsigned int>(i);
}

__global__ void gatherColumnsKernel(const float* __restrict__ raw_xyz,
                                    const unsigned int* __restrict__ raw_src,
                                    const unsigned int* __restrict__ order, int n, float* xyz,
                                    unsigned int* src) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= n) return;
  const unsigned int s = order[j];
  const std::size_t a = 3 * static_cast<std::size_t>(s), b = 3 * static_cast<std::size_t>(j);
  xyz[b] = raw_xyz[a];
  xyz[b + 1] = raw_xyz[a + 1];
  xyz[b + 2] = raw_xyz[a + 2];
  src[j] = raw_src[s];
}

// ------------------------------------------------------------------ candidates and vote

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

// ------------------------------------------------------------------ tiles

__global__ void tileKeysKernel(const float* __restrict__ xyz, int n, bool local_planes,
                               double min_x, double min_y, double inv_tile,
                               unsigned long long* keys, unsigned int* vals) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  unsigned long long key = 0;
  if (local_planes) {
    const std::size_t s = 3 * static_cast<std::size_t>(i);
    const std::uint32_t tx = cellIndex(xyz[s], min_x, inv_tile);
    const std::uint32_t ty = cellIndex(xyz[s + 1], min_y, inv_tile);
    key = (static_cast<unsigned long long>(tx) << 32) | ty;
  }
  keys[i] = key;
  vals[i] = static_cast<unsigned int>(i);
}

__global__ void tileFlagsKernel(const unsigned long long* __restrict__ keys,
                                const unsigned int* __restrict__ order,
                                const std::uint8_t* __restrict__ voted, int n, unsigned int* heads,
                                unsigned int* vflags, unsigned int* gflags) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j > n) return;
  if (j == n) {
    heads[n] = vflags[n] = gflags[n] = 0;
    return;
  }
  heads[j] = j == 0 || keys[j] != keys[j - 1];
  vflags[j] = voted[order[j]];
  gflags[j] = voted[j];
}

__global__ void tileListsKernel(
    const unsigned int* __restrict__ heads, const unsigned int* __restrict__ tile_idx,
    const unsigned int* __restrict__ order, const std::uint8_t* __restrict__ voted,
    const unsigned int* __restrict__ vpos, const unsigned int* __restrict__ gpos, int n,
    unsigned int* tile_begin, unsigned int* vlist, unsigned int* glist) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= n) return;
  if (heads[j]) tile_begin[tile_idx[j]] = static_cast<unsigned int>(j);
  if (j == n - 1) tile_begin[tile_idx[n]] = static_cast<unsigned int>(n);
  const unsigned int o = order[j];
  if (voted[o]) vlist[vpos[j]] = o;
  if (voted[j]) glist[gpos[j]] = static_cast<unsigned int>(j);
}

// ------------------------------------------------------------------ RANSAC planes

/// Offset of point i from `o` in double (CPU: point(i) of fitPlaneRansac).
__device__ inline void offsetOf(const float* __restrict__ xyz, unsigned int i, const double o[3],
                                double q[3]) {
  const float* p = xyz + 3 * static_cast<std::size_t>(i);
  q[0] = p[0] - o[0];
  q[1] = p[1] - o[1];
  q[2] = p[2] - o[2];
}

/// Sums W values per point over the points i in [0, m) for which term(i, v) (it writes the W
/// values to v) returns true; the sums reach thread 0 (acc) and the count is returned there.
/// serial: the CPU's order, kChunk points staged at a time and thread 0 adding in index order;
/// else a fixed-order parallel sum (each thread ascending, then thread 0 over the threads).
/// `stage` holds (W + 1) * max(kChunk, blockDim.x) doubles.
template <int W, typename Term>
__device__ inline unsigned long long blockInlierSum(unsigned int m, bool serial, double* stage,
                                                   double acc[W], Term term) {
  const unsigned int tid = threadIdx.x, bd = blockDim.x;
  for (int w = 0; w < W; ++w) acc[w] = 0.0;
  unsigned long long count = 0;
  if (serial) {
    for (unsigned int base = 0; base < m; base += kChunk) {
      const unsigned int cnt = min(static_cast<unsigned int>(kChunk), m - base);
      __syncthreads();
      for (unsigned int t = tid; t < cnt; t += bd) {
        double* s = stage + (W + 1) * t;
        s[W] = term(base + t, s) ? 1.0 : 0.0;
      }
      __syncthreads();
      if (tid == 0) {
        for (unsigned int t = 0; t < cnt; ++t) {
          const double* s = stage + (W + 1) * t;
          if (s[W] == 0.0) continue;
          for (int w = 0; w < W; ++w) acc[w] += s[w];
          ++count;
        }
      }
    }
    return count;
  }
  for (unsigned int t = tid; t < m; t += bd) {
    double v[W];
    if (!term(t, v)) continue;
    for (int w = 0; w < W; ++w) acc[w] += v[w];
    ++count;
  }
  __syncthreads();
  for (int w = 0; w < W; ++w) stage[(W + 1) * tid + w] = acc[w];
  stage[(W + 1) * tid + W] = static_cast<double>(count);
  __syncthreads();
  if (tid == 0) {
    double n = 0.0;
    for (int w = 0; w < W; ++w) acc[w] = 0.0;
    for (unsigned int t = 0; t < bd; ++t) {
      for (int w = 0; w < W; ++w) acc[w] += stage[(W + 1) * t + w];
      n += stage[(W + 1) * t + W];
    }
    count = static_cast<unsigned long long>(n);
  }
  return count;
}


/// CPU: fitPlaneRansac, one block per plane; the result is valid in thread 0.
__device__ void fitPlaneBlock(const float* __restrict__ xyz, const unsigned int* __restrict__ idx,
                              unsigned int m, const GroundParamsDev& p, std::uint64_t seed,
                              bool hypotheses_only, float* evp, double* stage, unsigned int* red,
                              double* shd, PlaneDev* out) {
  const int tid = threadIdx.x, bd = blockDim.x;
  PlaneDev best;
  best.n[0] = best.n[1] = 0.0;
  best.n[2] = 1.0;
  best.d = 0.0;
  best.o[0] = best.o[1] = best.o[2] = 0.0;
  best.valid = 0;
  *out = best;
  if (m < 3) return;
  {
    const float* o = xyz + 3 * static_cast<std::size_t>(idx[0]);
    best.o[0] = o[0];
    best.o[1] = o[1];
    best.o[2] = o[2];
  }
  const double thr = p.plane_distance, tilt = p.min_abs_nz;
  // Score on an evenly strided subset (CPU: eval).
  const unsigned int stride = (m + kEvalMax - 1) / kEvalMax;
  const unsigned int ne = (m + stride - 1) / stride;
  __syncthreads();  // evp of the previous item is no longer read
  for (unsigned int e = tid; e < ne; e += bd) {
    const float* q = xyz + 3 * static_cast<std::size_t>(idx[e * stride]);
    evp[3 * e] = q[0];
    evp[3 * e + 1] = q[1];
    evp[3 * e + 2] = q[2];
  }
  __syncthreads();

  SplitMix64 rng(seed);
  unsigned int best_count = 0;
  double best_n[3] = {0.0, 0.0, 1.0}, best_d = 0.0;
  double needed = p.iterations;
  for (int it = 0; it < p.iterations && it < needed; ++it) {  // uniform over the block
    const std::uint64_t a = rng.next() % m, b = rng.next() % m, c = rng.next() % m;
    if (a == b || a == c || b == c) continue;
    double pa[3], pb[3], pc[3];
    offsetOf(xyz, idx[a], best.o, pa);
    offsetOf(xyz, idx[b], best.o, pb);
    offsetOf(xyz, idx[c], best.o, pc);
    const double u[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
    const double v[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
    double nrm[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                     u[0] * v[1] - u[1] * v[0]};
    const double len = sqrt((nrm[0] * nrm[0] + nrm[1] * nrm[1]) + nrm[2] * nrm[2]);
    if (!(len > 1e-9)) continue;  // collinear or duplicate sample
    nrm[0] /= len;
    nrm[1] /= len;
    nrm[2] /= len;
    if (fabs(nrm[2]) < tilt) continue;
    const double d = -dot3(nrm, pa);
    unsigned int local = 0;
    for (unsigned int e = tid; e < ne; e += bd) {
      const double q[3] = {evp[3 * e] - best.o[0], evp[3 * e + 1] - best.o[1],
                           evp[3 * e + 2] - best.o[2]};
      local += fabs(dot3(nrm, q) + d) <= thr;
    }
    const unsigned int count = blockSum(local, red);
    if (count > best_count) {
      best_count = count;
      best_n[0] = nrm[0];
      best_n[1] = nrm[1];
      best_n[2] = nrm[2];
      best_d = d;
      const double w = static_cast<double>(count) / static_cast<double>(ne);
      const double fail = 1.0 - w * w * w;
      needed = fail <= 0.0 ? 0.0 : ceil(log(0.01) / log(fail));
    }
  }
  if (best_count < 3) {
    if (tid == 0) *out = best;
    return;
  }
  if (hypotheses_only) {  // refined by the grid-wide kernels (globalRefine*)
    best.n[0] = best_n[0];
    best.n[1] = best_n[1];
    best.n[2] = best_n[2];
    best.d = best_d;
    best.valid = kPlaneNeedsRefinement;
    if (tid == 0) *out = best;
    return;
  }

  // Least-squares refinement on all inliers: mean, then centred covariance.
  const bool serial = m <= kSerialRefineMax;
  const auto inlier = [&](unsigned int i, double q[3]) {
    offsetOf(xyz, idx[i], best.o, q);
    return fabs(dot3(best_n, q) + best_d) <= thr;
  };
  double mean[3];
  const unsigned long long inliers =
      blockInlierSum<3>(m, serial, stage, mean, [&](unsigned int i, double* v) {
        return inlier(i, v);
      });
  best.n[0] = best_n[0];
  best.n[1] = best_n[1];
  best.n[2] = best_n[2];
  best.d = best_d;
  best.valid = 1;
  __syncthreads();
  if (tid == 0) {
    shd[0] = inliers < 3 ? 0.0 : 1.0;
    if (inliers >= 3) {
      const double di = static_cast<double>(inliers);
      shd[1] = mean[0] / di;
      shd[2] = mean[1] / di;
      shd[3] = mean[2] / di;
    }
  }
  __syncthreads();
  if (shd[0] == 0.0) {
    if (tid == 0) *out = best;
    return;
  }
  const double mu[3] = {shd[1], shd[2], shd[3]};
  double cov[6];  // xx xy xz yy yz zz
  blockInlierSum<6>(m, serial, stage, cov, [&](unsigned int i, double* v) {
    double q[3];
    const bool in = inlier(i, q);
    const double r[3] = {q[0] - mu[0], q[1] - mu[1], q[2] - mu[2]};
    v[0] = r[0] * r[0];
    v[1] = r[0] * r[1];
    v[2] = r[0] * r[2];
    v[3] = r[1] * r[1];
    v[4] = r[1] * r[2];
    v[5] = r[2] * r[2];
    return in;
  });
  if (tid == 0) {
    const double a[3][3] = {
        {cov[0], cov[1], cov[2]}, {cov[1], cov[3], cov[4]}, {cov[2], cov[4], cov[5]}};
    double ev[3], nv[3];
    eigenDirect3(a, ev, nv);
    if (dot3(nv, best_n) < 0.0) {
      nv[0] = -nv[0];
      nv[1] = -nv[1];
      nv[2] = -nv[2];
    }
    if (isfinite(nv[0]) && fabs(nv[2]) >= tilt) {
      best.n[0] = nv[0];
      best.n[1] = nv[1];
      best.n[2] = nv[2];
      best.d = -dot3(nv, mu);
    }
    *out = best;
  }
}

__global__ void __launch_bounds__(kPlaneThreads)
    planesKernel(const float* __restrict__ xyz, const unsigned long long* __restrict__ keys,
                 const unsigned int* __restrict__ tile_begin, const unsigned int* ntiles_dev,
                 const unsigned int* __restrict__ vpos, const unsigned int* __restrict__ vlist,
                 const unsigned int* __restrict__ glist, const unsigned int* gcount,
                 const unsigned int* need_global_dev, const GroundParamsDev p, PlaneDev* planes,
                 unsigned int* work) {
  __shared__ float evp[3 * kEvalMax];
  __shared__ double stage[7 * kChunk];
  __shared__ unsigned int red[32];
  __shared__ double shd[4];
  __shared__ unsigned int item_s;
  const unsigned int ntiles = *ntiles_dev;
  const bool need_global = !p.local_planes || *need_global_dev;
  for (;;) {
    if (threadIdx.x == 0) item_s = atomicAdd(work, 1u);
    __syncthreads();
    const unsigned int item = item_s;
    __syncthreads();
    if (item > ntiles) break;
    PlaneDev plane;
    if (item == 0) {
      if (need_global) {
        const unsigned int m = *gcount;
        fitPlaneBlock(xyz, glist, m, p, p.seed, m > kSerialRefineMax, evp, stage, red, shd,
                      &plane);
      } else {
        plane.valid = 0;
      }
    } else {
      const unsigned int t = item - 1, b = tile_begin[t], e = tile_begin[t + 1];
      const unsigned int m = vpos[e] - vpos[b];
      if (p.local_planes && m >= kMinTilePoints) {
        const std::uint64_t seed = p.seed ^ (keys[b] * 0x9e3779b97f4a7c15ULL);
        fitPlaneBlock(xyz, vlist + vpos[b], m, p, seed, false, evp, stage, red, shd, &plane);
      } else {
        plane.valid = 0;
      }
    }
    if (threadIdx.x == 0) planes[item] = plane;
  }
}

/// need_global = some tile has fewer than kMinTilePoints voted points (CPU: need_global).
__global__ void needGlobalKernel(const unsigned int* __restrict__ tile_begin,
                                 const unsigned int* ntiles_dev,
                                 const unsigned int* __restrict__ vpos, unsigned int* need_global) {
  const unsigned int t = blockIdx.x * blockDim.x + threadIdx.x;
  const bool few =
      t < *ntiles_dev && vpos[tile_begin[t + 1]] - vpos[tile_begin[t]] < kMinTilePoints;
  if (__syncthreads_or(few) && threadIdx.x == 0) *need_global = 1;
}

/// Fixed-order block sum of `v[0..c)` per thread (thread t's values at sh[t * c + i]); result in
/// thread 0's `v`.
template <int C>
__device__ inline void blockSumFixed(double (&v)[C], double* sh) {
  __syncthreads();
  for (int i = 0; i < C; ++i) sh[threadIdx.x * C + i] = v[i];
  __syncthreads();
  for (int half = blockDim.x / 2; half > 0; half >>= 1) {
    if (threadIdx.x < half) {
      for (int i = 0; i < C; ++i) sh[threadIdx.x * C + i] += sh[(threadIdx.x + half) * C + i];
    }
    __syncthreads();
  }
  for (int i = 0; i < C; ++i) v[i] = sh[i];
}

/// Grid-wide least-squares refinement of a large cloud-wide plane (planes[0].valid ==
/// kPlaneNeedsRefinement): pass 0 sums the inliers per block, pass 1 their centred products
/// (the mean from all blocks' sums, added in block order), pass 2 (one block) finishes the plane.
/// Every sum has a fixed order, so the result is deterministic.
__global__ void __launch_bounds__(kThreads)
    globalRefineKernel(int pass, const float* __restrict__ xyz,
                       const unsigned int* __restrict__ glist, const unsigned int* gcount,
                       const GroundParamsDev p, PlaneDev* planes, double* partial) {
  __shared__ double sh[kThreads * 6];
  const PlaneDev pl = planes[0];
  if (pl.valid != kPlaneNeedsRefinement) return;
  const unsigned int m = *gcount;
  const unsigned int per = (m + gridDim.x - 1) / gridDim.x;
  const double thr = p.plane_distance;
  double mu[3] = {0.0, 0.0, 0.0};
  double inliers = 0.0;
  if (pass >= 1) {  // the mean, from the pass-0 partials in block order
    for (int b = 0; b < kRefineBlocks; ++b) {
      mu[0] += partial[4 * b];
      mu[1] += partial[4 * b + 1];
      mu[2] += partial[4 * b + 2];
      inliers += partial[4 * b + 3];
    }
    if (inliers >= 3.0) {
      mu[0] /= inliers;
      mu[1] /= inliers;
      mu[2] /= inliers;
    }
  }
  if (pass == 2) {
    if (threadIdx.x != 0) return;
    PlaneDev out = pl;
    out.valid = 1;
    if (inliers >= 3.0) {
      double cov[6] = {0, 0, 0, 0, 0, 0};
      const double* part = partial + 4 * kRefineBlocks;
      for (int b = 0; b < kRefineBlocks; ++b) {
        for (int c = 0; c < 6; ++c) cov[c] += part[6 * b + c];
      }
      const double a[3][3] = {
          {cov[0], cov[1], cov[2]}, {cov[1], cov[3], cov[4]}, {cov[2], cov[4], cov[5]}};
      double ev[3], nv[3];
      eigenDirect3(a, ev, nv);
      if (dot3(nv, pl.n) < 0.0) {
        nv[0] = -nv[0];
        nv[1] = -nv[1];
        nv[2] = -nv[2];
      }
      if (isfinite(nv[0]) && fabs(nv[2]) >= p.min_abs_nz) {
        out.n[0] = nv[0];
        out.n[1] = nv[1];
        out.n[2] = nv[2];
        out.d = -dot3(nv, mu);
      }
    }
    planes[0] = out;
    return;
  }
  const unsigned int b0 = blockIdx.x * per, b1 = min(m, b0 + per);
  if (pass == 0) {
    double v[4] = {0.0, 0.0, 0.0, 0.0};
    for (unsigned int t = b0 + threadIdx.x; t < b1; t += blockDim.x) {
      double q[3];
      offsetOf(xyz, glist[t], pl.o, q);
      if (fabs(dot3(pl.n, q) + pl.d) <= thr) {
        v[0] += q[0];
        v[1] += q[1];
        v[2] += q[2];
        v[3] += 1.0;
      }
    }
    blockSumFixed(v, sh);
    if (threadIdx.x == 0) {
      for (int c = 0; c < 4; ++c) partial[4 * blockIdx.x + c] = v[c];
    }
    return;
  }
  double v[6] = {0, 0, 0, 0, 0, 0};
  if (inliers >= 3.0) {
    for (unsigned int t = b0 + threadIdx.x; t < b1; t += blockDim.x) {
      double q[3];
      offsetOf(xyz, glist[t], pl.o, q);
      if (fabs(dot3(pl.n, q) + pl.d) <= thr) {
        const double r[3] = {q[0] - mu[0], q[1] - mu[1], q[2] - mu[2]};
        v[0] += r[0] * r[0];
        v[1] += r[0] * r[1];
        v[2] += r[0] * r[2];
        v[3] += r[1] * r[1];
        v[4] += r[1] * r[2];
        v[5] += r[2] * r[2];
      }
    }
  }
  blockSumFixed(v, sh);
  if (threadIdx.x == 0) {
    for (int c = 0; c < 6; ++c) partial[4 * kRefineBlocks + 6 * blockIdx.x + c] = v[c];
  }
}

// ------------------------------------------------------------------ distance test

__device__ inline double planeDistance(const PlaneDev& pl, const float* p) {
  return ((pl.n[0] * (p[0] - pl.o[0]) + pl.n[1] * (p[1] - pl.o[1])) + pl.n[2] * (p[2] - pl.o[2])) +
         pl.d;
}

/// Min of v over the block (all threads get it); `warp_s` holds one word per warp.
__device__ inline double blockMin(double v, double* warp_s) {
  for (int o = 16; o > 0; o >>= 1) v = fmin(v, __shfl_xor_sync(0xffffffffu, v, o));
  if ((threadIdx.x & 31) == 0) warp_s[threadIdx.x >> 5] = v;
  __syncthreads();
  double r = warp_s[0];
  for (unsigned int w = 1; w < blockDim.x / 32; ++w) r = fmin(r, warp_s[w]);
  __syncthreads();
  return r;
}

__global__ void __launch_bounds__(kThreads)
    classifyKernel(const float* __restrict__ xyz, const unsigned int* __restrict__ src,
                   const unsigned int* __restrict__ order, const std::uint8_t* __restrict__ voted,
                   const unsigned int* __restrict__ tile_begin, const unsigned int* ntiles_dev,
                   const unsigned int* __restrict__ vpos, const unsigned int* __restrict__ vlist,
                   const GroundParamsDev p, const PlaneDev* __restrict__ planes,
                   std::uint8_t* labels, unsigned int* ground_count, unsigned int* work) {
  __shared__ unsigned int item_s;
  __shared__ double band[2];
  __shared__ double floor_min_s[kThreads / 32];
  __shared__ unsigned int floor_count_s[kThreads / 32];
  const unsigned int ntiles = *ntiles_dev;
  unsigned int ground = 0;
  for (;;) {
    if (threadIdx.x == 0) item_s = atomicAdd(work, 1u);
    __syncthreads();
    const unsigned int t = item_s;
    __syncthreads();
    if (t >= ntiles) break;
    const unsigned int b = tile_begin[t], e = tile_begin[t + 1];
    const unsigned int m = vpos[e] - vpos[b];
    PlaneDev plane = planes[0];
    if (p.local_planes && m >= kMinTilePoints && planes[1 + t].valid) plane = planes[1 + t];
    if (!plane.valid) continue;  // uniform
    if (p.local_planes && m < kMinTilePoints && p.floor_share > 0.0) {
      // As the CPU (plane.cpp, sparse-tile floor): the cloud-wide plane moved to the tile's
      // lowest point when enough of the tile lies within plane_distance above it. Min and count
      // are exact, so the order of the reduction does not matter.
      const double up = plane.n[2] < 0.0 ? -1.0 : 1.0;
      double low = HUGE_VAL;
      for (unsigned int j = b + threadIdx.x; j < e; j += blockDim.x) {
        low = fmin(low, up * planeDistance(plane, xyz + 3 * static_cast<std::size_t>(order[j])));
      }
      low = blockMin(low, floor_min_s);
      if (low >= -p.floor_max_shift && low <= p.floor_max_shift) {  // uniform
        unsigned int on_floor = 0;
        for (unsigned int j = b + threadIdx.x; j < e; j += blockDim.x) {
          const double h =
              up * planeDistance(plane, xyz + 3 * static_cast<std::size_t>(order[j]));
          on_floor += h >= low && h <= low + p.plane_distance;
        }
        on_floor = blockSum(on_floor, floor_count_s);
        if (static_cast<double>(on_floor) >= p.floor_share * static_cast<double>(e - b)) {
          plane.d -= up * low;
        }
      }
    }
    double lo = -p.plane_distance, hi = p.plane_distance;
    if (p.std_filter) {  // band of the voted points' distances, summed in the CPU's order
      if (threadIdx.x == 0) {
        double s = 0.0, s2 = 0.0;
        unsigned long long c = 0;
        for (unsigned int v = vpos[b]; v < vpos[e]; ++v) {
          const double d = planeDistance(plane, xyz + 3 * static_cast<std::size_t>(vlist[v]));
          if (fabs(d) <= p.plane_distance) {
            s += d;
            s2 += d * d;
            ++c;
          }
        }
        if (c > 0) {
          const double mean = s / c;
          const double sd = sqrt(fmax(0.0, s2 / c - mean * mean));
          lo = fmax(lo, mean - p.std_multiplier * sd);
          hi = fmin(hi, mean + p.std_multiplier * sd);
        }
        band[0] = lo;
        band[1] = hi;
      }
      __syncthreads();
      lo = band[0];
      hi = band[1];
      __syncthreads();
    }
    for (unsigned int j = b + threadIdx.x; j < e; j += blockDim.x) {
      const unsigned int i = order[j];
      if (!voted[i] && !p.plane_all_points) continue;
      const double d = planeDistance(plane, xyz + 3 * static_cast<std::size_t>(i));
      if (d >= lo && d <= hi) {
        labels[src[i]] = 1;
        ++ground;
      }
    }
  }
  for (int o = 16; o > 0; o >>= 1) ground += __shfl_xor_sync(0xffffffffu, ground, o);
  if ((threadIdx.x & 31) == 0 && ground) atomicAdd(ground_count, ground);
}

}  // namespace

void launchFiniteFlags(const float* in, int n, unsigned int* flags, cudaStream_t st) {
  finiteFlagsKernel<<<blocksFor(static_cast<std::size_t>(n) + 1, kThreads), kThreads, 0, st>>>(
      in, n, flags);
  GF_CUDA_CHECK_LAUNCH();
}

void launchCompact(const float* in, const unsigned int* flags, const unsigned int* pos, int n,
                   float* raw_xyz, unsigned int* raw_src, int* bounds, cudaStream_t st) {
  initBounds2Kernel<<<1, 32, 0, st>>>(bounds);
  GF_CUDA_CHECK_LAUNCH();
  if (n == 0) return;
  compactKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(in, flags, pos, n, raw_xyz, raw_src,
                                                             bounds);
  GF_CUDA_CHECK_LAUNCH();
}

void launchColumnKeys(const float* raw_xyz, int n, double min_x, double min_y, double inv_cell,
                      unsigned long long* keys, unsigned int* vals, cudaStream_t st) {
  columnKeysKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(raw_xyz, n, min_x, min_y, inv_cell,
                                                                keys, vals);
  GF_CUDA_CHECK_LAUNCH();
}

void launchGatherColumns(const float* raw_xyz, const unsigned int* raw_src,
                         const unsigned int* order, int n, float* xyz, unsigned int* src,
                         cudaStream_t st) {
  gatherColumnsKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(raw_xyz, raw_src, order, n, xyz,
                                                                   src);
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

void launchTileKeys(const float* xyz, int n, bool local_planes, double min_x, double min_y,
                    double inv_tile, unsigned long long* keys, unsigned int* vals,
                    cudaStream_t st) {
  tileKeysKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(xyz, n, local_planes, min_x, min_y,
                                                              inv_tile, keys, vals);
  GF_CUDA_CHECK_LAUNCH();
}

void launchTileFlags(const unsigned long long* sorted_keys, const unsigned int* order,
                     const std::uint8_t* voted, int n, unsigned int* heads, unsigned int* vflags,
                     unsigned int* gflags, cudaStream_t st) {
  tileFlagsKernel<<<blocksFor(static_cast<std::size_t>(n) + 1, kThreads), kThreads, 0, st>>>(
      sorted_keys, order, voted, n, heads, vflags, gflags);
  GF_CUDA_CHECK_LAUNCH();
}

void launchTileLists(const unsigned int* heads, const unsigned int* tile_idx,
                     const unsigned int* order, const std::uint8_t* voted, const unsigned int* vpos,
                     const unsigned int* gpos, int n, unsigned int* tile_begin, unsigned int* vlist,
                     unsigned int* glist, cudaStream_t st) {
  tileListsKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(heads, tile_idx, order, voted, vpos,
                                                               gpos, n, tile_begin, vlist, glist);
  GF_CUDA_CHECK_LAUNCH();
}

void launchPlanes(const float* xyz, const unsigned long long* sorted_keys,
                  const unsigned int* tile_begin, const unsigned int* ntiles,
                  const unsigned int* vpos, const unsigned int* vlist, const unsigned int* glist,
                  const unsigned int* gcount, const GroundParamsDev& p, PlaneDev* planes,
                  unsigned int* work, unsigned int* need_global, double* partial,
                  std::size_t tiles_max, int blocks, cudaStream_t st) {
  if (p.local_planes) {
    needGlobalKernel<<<blocksFor(tiles_max, kThreads), kThreads, 0, st>>>(tile_begin, ntiles, vpos,
                                                                          need_global);
    GF_CUDA_CHECK_LAUNCH();
  }
  planesKernel<<<blocks, kPlaneThreads, 0, st>>>(xyz, sorted_keys, tile_begin, ntiles, vpos, vlist,
                                                 glist, gcount, need_global, p, planes, work);
  GF_CUDA_CHECK_LAUNCH();
  for (int pass = 0; pass < 3; ++pass) {
    globalRefineKernel<<<pass == 2 ? 1 : kRefineBlocks, kThreads, 0, st>>>(pass, xyz, glist, gcount,
                                                                           p, planes, partial);
    GF_CUDA_CHECK_LAUNCH();
  }
}

std::size_t refinePartialBytes() { return sizeof(double) * 10 * kRefineBlocks; }

void launchClassify(const float* xyz, const unsigned int* src, const unsigned int* order,
                    const std::uint8_t* voted, const unsigned int* tile_begin,
                    const unsigned int* ntiles, const unsigned int* vpos, const unsigned int* vlist,
                    const GroundParamsDev& p, const PlaneDev* planes, std::uint8_t* labels,
                    unsigned int* ground_count, unsigned int* work, int blocks, cudaStream_t st) {
  classifyKernel<<<blocks, kThreads, 0, st>>>(xyz, src, order, voted, tile_begin, ntiles, vpos,
                                              vlist, p, planes, labels, ground_count, work);
  GF_CUDA_CHECK_LAUNCH();
}

}  // namespace cuda_impl
}  // namespace ground_filter
