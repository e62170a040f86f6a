// RANSAC planes and their least-squares refinement (see ground_planes.cuh).
#include <cmath>

#include "cuda_util.cuh"
#include "ground_planes.cuh"
#include "knn_grid.cuh"
#include "knn_pca.cuh"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

namespace {

constexpr int kThreads = kGroundThreads;
constexpr int kPlaneThreads = normal::kPlaneSumLanes;  // one thread per lane of the plane sums
constexpr int kPlaneNeedsRefinement = 2;  // PlaneDev::valid of a hypothesis awaiting refinement
constexpr int kRefineBlocks = 264;        // blocks of the grid-wide refinement

using normal::kMinTilePoints;
using normal::SplitMix64;
constexpr unsigned int kEvalMax = normal::kRansacEvalPoints;

/// Offset of point i from `o` in double (CPU: point(i) of fitPlaneRansac).
__device__ inline void offsetOf(const float* __restrict__ xyz, unsigned int i, const double o[3],
                                double q[3]) {
  const float* p = xyz + 3 * static_cast<std::size_t>(i);
  q[0] = p[0] - o[0];
  q[1] = p[1] - o[1];
  q[2] = p[2] - o[2];
}

/// Sums W values per point over the points i in [0, m) for which term(i, v) (it writes the W
/// values to v) returns true; the sums reach thread 0 (acc) and the count is returned there. The
/// CPU's order (fitPlaneRansac): thread t adds the points t, t + kPlaneSumLanes, ... ascending,
/// then thread 0 adds the threads' sums in thread order. `stage` holds (W + 1) * blockDim.x
/// doubles; blockDim.x == kPlaneSumLanes.
template <int W, typename Term>
__device__ inline unsigned long long blockInlierSum(unsigned int m, double* stage, double acc[W],
                                                    Term term) {
  const unsigned int tid = threadIdx.x, bd = blockDim.x;
  for (int w = 0; w < W; ++w) acc[w] = 0.0;
  unsigned long long count = 0;
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

/// Horizontal distance from the sensor to `at` (relative to the plane's origin `o`).
__device__ inline double reach(const GroundParamsDev& p, const double o[3], const double at[3]) {
  return normal::horizontalDistance(p.sensor[0] - o[0], p.sensor[1] - o[1], at[0], at[1]);
}

/// normal::planeAboveSensor() for the plane n.q + d = 0 relative to the origin `o`, its nearest
/// support `r` from the sensor.
__device__ inline bool aboveSensor(const GroundParamsDev& p, const double o[3], const double n[3],
                                   double d, double r, bool draw) {
  return normal::planeAboveSensor(n[0], n[1], n[2], d, p.sensor[0] - o[0], p.sensor[1] - o[1],
                                  p.sensor[2] - o[2], r, draw);
}

/// The best RANSAC hypothesis: its inlier count on the eval subset, normal and offset.
struct Hypothesis {
  unsigned int count;
  double n[3];
  double d;
};

/// Stages the evenly strided eval subset of the m points idx[] in `evp` (3 floats a point);
/// returns its size (CPU: eval of fitPlaneRansac).
__device__ inline unsigned int stageEvalPoints(const float* __restrict__ xyz,
                                               const unsigned int* __restrict__ idx, unsigned int m,
                                               float* evp) {
  const int tid = threadIdx.x, bd = blockDim.x;
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
  return ne;
}

/// Warps of a plane block: each scores one RANSAC draw at a time.
constexpr int kPlaneWarps = kPlaneThreads / 32;

/// The RANSAC draws (CPU: the loop of fitPlaneRansac): planes through 3 of the m points,
/// relative to the origin `o`, scored on the ne staged eval points. Warp w scores draw it0 + w;
/// the block then takes the scores in draw order with the CPU's adaptive stop, so the result is
/// the CPU's (the draws of a batch past the stop are discarded). `batch` holds kPlaneWarps.
__device__ inline Hypothesis ransacHypotheses(const float* __restrict__ xyz,
                                              const unsigned int* __restrict__ idx, unsigned int m,
                                              unsigned int ne, const GroundParamsDev& p,
                                              std::uint64_t seed, const double o[3], bool check,
                                              const float* evp, Hypothesis* batch) {
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  const double thr = p.plane_distance, tilt = p.min_abs_nz;
  const int iterations = p.ransac_iterations;
  Hypothesis best;
  best.count = 0;
  best.n[0] = 0.0;
  best.n[1] = 0.0;
  best.n[2] = 1.0;
  best.d = 0.0;
  double needed = iterations;
  for (int it0 = 0; it0 < iterations && it0 < needed; it0 += kPlaneWarps) {
    const int it = it0 + warp;
    Hypothesis h = best;  // a draw that gives no plane scores 0: the CPU skips it
    h.count = 0;
    if (it < iterations) {
      // The draws of iteration `it` are the generator's 3 it-th to (3 it + 2)-th.
      SplitMix64 rng(seed);
      rng.skip(3ull * static_cast<std::uint64_t>(it));
      const std::uint64_t a = rng.next() % m, b = rng.next() % m, c = rng.next() % m;
      if (a != b && a != c && b != c) {
        double pa[3], pb[3], pc[3];
        offsetOf(xyz, idx[a], o, pa);
        offsetOf(xyz, idx[b], o, pb);
        offsetOf(xyz, idx[c], o, pc);
        const double u[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
        const double v[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
        double nrm[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                         u[0] * v[1] - u[1] * v[0]};
        const double len = sqrt((nrm[0] * nrm[0] + nrm[1] * nrm[1]) + nrm[2] * nrm[2]);
        if (len > 1e-9) {  // else collinear or duplicate sample
          nrm[0] /= len;
          nrm[1] /= len;
          nrm[2] /= len;
          const double d = -dot3(nrm, pa);
          if (fabs(nrm[2]) >= tilt &&
              !(check && aboveSensor(p, o, nrm, d,
                                     normal::drawReach(p.sensor[0] - o[0], p.sensor[1] - o[1],
                                                       pa[0], pa[1], pb[0], pb[1], pc[0], pc[1]),
                                     true))) {
            unsigned int local = 0;
            for (unsigned int e = lane; e < ne; e += 32) {
              const double q[3] = {evp[3 * e] - o[0], evp[3 * e + 1] - o[1], evp[3 * e + 2] - o[2]};
              local += fabs(dot3(nrm, q) + d) <= thr;
            }
            for (int off = 16; off > 0; off >>= 1)
              local += __shfl_xor_sync(0xffffffffu, local, off);
            h.count = local;
            h.n[0] = nrm[0];
            h.n[1] = nrm[1];
            h.n[2] = nrm[2];
            h.d = d;
          }
        }
      }
    }
    __syncthreads();  // the previous batch is read
    if (lane == 0) batch[warp] = h;
    __syncthreads();
    bool stop = false;
    for (int w = 0; w < kPlaneWarps; ++w) {  // in draw order, as the CPU's loop
      if (!(it0 + w < iterations && it0 + w < needed)) {
        stop = true;
        break;
      }
      const Hypothesis& c = batch[w];
      if (c.count > best.count) {
        best = c;
        const double wr = static_cast<double>(c.count) / static_cast<double>(ne);
        const double fail = 1.0 - wr * wr * wr;
        needed = fail <= 0.0 ? 0.0 : ceil(log(0.01) / log(fail));
      }
    }
    if (stop) break;
  }
  return best;
}

/// The least-squares plane of the inliers' covariance `cov` (xx xy xz yy yz zz, about their
/// mean `mu`) replaces *plane's normal and offset (turned to its normal's side) when it lies in
/// the tilt window; one that passes above the sensor (`check`) leaves no plane (CPU: the end of
/// fitPlaneRansac).
__device__ inline void finishRefit(const GroundParamsDev& p, bool check, const double cov[6],
                                   const double mu[3], PlaneDev* plane) {
  const double a[3][3] = {
      {cov[0], cov[1], cov[2]}, {cov[1], cov[3], cov[4]}, {cov[2], cov[4], cov[5]}};
  double ev[3], nv[3];
  eigenDirect3(a, ev, nv);
  if (dot3(nv, plane->n) < 0.0) {
    nv[0] = -nv[0];
    nv[1] = -nv[1];
    nv[2] = -nv[2];
  }
  if (!(isfinite(nv[0]) && fabs(nv[2]) >= p.min_abs_nz)) return;
  if (check && normal::refitJudged(ev[1], ev[2]) &&
      aboveSensor(p, plane->o, nv, -dot3(nv, mu), reach(p, plane->o, mu), false)) {
    plane->valid = 0;  // the refit passes above the sensor: no plane (CPU: false)
    return;
  }
  plane->n[0] = nv[0];
  plane->n[1] = nv[1];
  plane->n[2] = nv[2];
  plane->d = -dot3(nv, mu);
}

/// Least-squares refinement of the hypothesis `h` on all its inliers among the m points: mean,
/// then centred covariance, then the smallest eigenvector (CPU: the end of fitPlaneRansac).
/// `best` holds the origin; the plane is written to *out in thread 0.
__device__ inline void refinePlane(const float* __restrict__ xyz,
                                   const unsigned int* __restrict__ idx, unsigned int m,
                                   const GroundParamsDev& p, const Hypothesis& h, PlaneDev best,
                                   bool check, double* stage, double* shd, PlaneDev* out) {
  const int tid = threadIdx.x;
  const double thr = p.plane_distance;
  const double* best_n = h.n;
  const double best_d = h.d;
  const auto inlier = [&](unsigned int i, double q[3]) {
    offsetOf(xyz, idx[i], best.o, q);
    return fabs(dot3(best_n, q) + best_d) <= thr;
  };
  double mean[3];
  const unsigned long long inliers =
      blockInlierSum<3>(m, stage, mean, [&](unsigned int i, double* v) { return inlier(i, v); });
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
  blockInlierSum<6>(m, stage, cov, [&](unsigned int i, double* v) {
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
    finishRefit(p, check, cov, mu, &best);
    *out = best;
  }
}

/// CPU: fitPlaneRansac, one block per plane; the result is valid in thread 0.
__device__ void fitPlaneBlock(const float* __restrict__ xyz, const unsigned int* __restrict__ idx,
                              unsigned int m, const GroundParamsDev& p, std::uint64_t seed,
                              bool hypotheses_only, bool check, float* evp, double* stage,
                              Hypothesis* batch, double* shd, PlaneDev* out) {
  const int tid = threadIdx.x;
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
  // Score on an evenly strided subset (CPU: eval).
  const unsigned int ne = stageEvalPoints(xyz, idx, m, evp);
  const Hypothesis h = ransacHypotheses(xyz, idx, m, ne, p, seed, best.o, check, evp, batch);
  if (h.count < 3) {
    if (tid == 0) *out = best;
    return;
  }
  if (hypotheses_only) {  // refined by the grid-wide kernels (globalRefine*)
    best.n[0] = h.n[0];
    best.n[1] = h.n[1];
    best.n[2] = h.n[2];
    best.d = h.d;
    best.valid = kPlaneNeedsRefinement;
    if (tid == 0) *out = best;
    return;
  }
  refinePlane(xyz, idx, m, p, h, best, check, stage, shd, out);
}

/// Whether no plane may pass above the sensor in this scan (CPU: PlaneStage::run()).
/// `sensor_counts`: the near voted points under the sensor, the near voted points.
__device__ inline bool sensorCheck(const GroundParamsDev& p, const unsigned int* sensor_counts) {
  return p.sensor_check && normal::sensorAboveGround(sensor_counts[0], sensor_counts[1]);
}

/// Counts the voted points near the sensor and those of them under it
/// (normal::sensorAboveGround()), one atomic per warp.
__global__ void __launch_bounds__(kThreads)
    sensorBelowKernel(const float* __restrict__ xyz, const std::uint8_t* __restrict__ voted, int n,
                      const GroundParamsDev p, unsigned int* counts) {
  unsigned int below = 0, near = 0;
  for (int t = blockIdx.x * blockDim.x + threadIdx.x; t < n; t += gridDim.x * blockDim.x) {
    if (!voted[t]) continue;
    const float* q = xyz + 3 * static_cast<std::size_t>(t);
    if (!normal::nearSensor(q[0] - p.sensor[0], q[1] - p.sensor[1])) continue;
    ++near;
    below += normal::belowSensor(q[2], p.sensor[2]);
  }
  for (int off = 16; off > 0; off >>= 1) {
    below += __shfl_xor_sync(0xffffffffu, below, off);
    near += __shfl_xor_sync(0xffffffffu, near, off);
  }
  if ((threadIdx.x & 31) == 0 && near) {
    atomicAdd(counts, below);
    atomicAdd(counts + 1, near);
  }
}

/// The lowest voted z of each overhead column (ordered ints), where no sensor judges planes.
__global__ void __launch_bounds__(kThreads)
    columnLowKernel(const float* __restrict__ xyz, const std::uint8_t* __restrict__ voted, int n,
                    const normal::OverheadGrid og, const GroundParamsDev p,
                    const unsigned int* sensor_counts, int* column_low) {
  if (sensorCheck(p, sensor_counts)) return;
  for (int t = blockIdx.x * blockDim.x + threadIdx.x; t < n; t += gridDim.x * blockDim.x) {
    if (!voted[t]) continue;
    const float* q = xyz + 3 * static_cast<std::size_t>(t);
    atomicMin(column_low + normal::overheadColumn(og, q[0], q[1]), floatToOrdered(q[2]));
  }
}

/// Clears the voted flag of the points over other voted ones (normal::overheadPoint()).
__global__ void __launch_bounds__(kThreads)
    unvoteOverheadKernel(const float* __restrict__ xyz, std::uint8_t* voted, int n,
                         const normal::OverheadGrid og, const GroundParamsDev p,
                         const unsigned int* sensor_counts, const int* __restrict__ column_low) {
  if (sensorCheck(p, sensor_counts)) return;
  for (int t = blockIdx.x * blockDim.x + threadIdx.x; t < n; t += gridDim.x * blockDim.x) {
    if (!voted[t]) continue;
    const float* q = xyz + 3 * static_cast<std::size_t>(t);
    const float low = orderedToFloat(column_low[normal::overheadColumn(og, q[0], q[1])]);
    if (normal::overheadPoint(q[2], low)) voted[t] = 0;
  }
}

__global__ void __launch_bounds__(kPlaneThreads)
    planesKernel(const float* __restrict__ xyz, const unsigned long long* __restrict__ keys,
                 int ybits, const unsigned int* __restrict__ tile_begin,
                 const unsigned int* ntiles_dev, const unsigned int* __restrict__ vpos,
                 const unsigned int* __restrict__ vlist, const unsigned int* __restrict__ glist,
                 const unsigned int* gcount, const unsigned int* need_global_dev,
                 const unsigned int* sensor_counts, const GroundParamsDev p, PlaneDev* planes,
                 unsigned int* work) {
  __shared__ float evp[3 * kEvalMax];
  __shared__ double stage[7 * kPlaneThreads];
  __shared__ Hypothesis batch[kPlaneWarps];
  __shared__ double shd[4];
  __shared__ unsigned int item_s;
  const unsigned int ntiles = *ntiles_dev;
  const bool check = sensorCheck(p, sensor_counts);
  const bool need_global = !p.local_planes || *need_global_dev || check;
  const std::uint64_t base_seed = normal::ransacBaseSeed(static_cast<std::uint32_t>(p.ransac_seed));
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
        fitPlaneBlock(xyz, glist, m, p, base_seed, m > kBlockRefineMax, check, evp, stage, batch,
                      shd, &plane);
      } else {
        plane.valid = 0;
      }
    } else {
      const unsigned int t = item - 1, b = tile_begin[t], e = tile_begin[t + 1];
      const unsigned int m = vpos[e] - vpos[b];
      if (p.local_planes && m >= kMinTilePoints) {
        // The seed of the CPU's key (tx << 32) | ty (plane.cpp), from the packed tx << ybits | ty.
        const unsigned long long key = keys[b];
        const std::uint64_t cpu_key = ((key >> ybits) << 32) | (key & ((1ull << ybits) - 1ull));
        const std::uint64_t seed = base_seed ^ (cpu_key * 0x9e3779b97f4a7c15ULL);
        fitPlaneBlock(xyz, vlist + vpos[b], m, p, seed, false, check, evp, stage, batch, shd,
                      &plane);
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
                       const unsigned int* sensor_counts, const GroundParamsDev p, PlaneDev* planes,
                       double* partial) {
  __shared__ double sh[kThreads * 6];
  __shared__ double part[10 * kRefineBlocks];  // the partials, staged: the serial sums read them
  const PlaneDev pl = planes[0];
  if (pl.valid != kPlaneNeedsRefinement) return;
  const unsigned int m = *gcount;
  const unsigned int per = (m + gridDim.x - 1) / gridDim.x;
  const double thr = p.plane_distance;
  double mu[3] = {0.0, 0.0, 0.0};
  double inliers = 0.0;
  if (pass >= 1) {  // the mean, from the pass-0 partials in block order
    const int staged = (pass == 2 ? 10 : 4) * kRefineBlocks;
    for (int i = threadIdx.x; i < staged; i += blockDim.x) part[i] = partial[i];
    __syncthreads();
    for (int b = 0; b < kRefineBlocks; ++b) {
      mu[0] += part[4 * b];
      mu[1] += part[4 * b + 1];
      mu[2] += part[4 * b + 2];
      inliers += part[4 * b + 3];
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
      const double* cov_part = part + 4 * kRefineBlocks;
      for (int b = 0; b < kRefineBlocks; ++b) {
        for (int c = 0; c < 6; ++c) cov[c] += cov_part[6 * b + c];
      }
      finishRefit(p, sensorCheck(p, sensor_counts), cov, mu, &out);
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

}  // namespace

void launchPlanes(const float* xyz, const unsigned long long* sorted_keys, int ybits,
                  const unsigned int* tile_begin, const unsigned int* ntiles,
                  const unsigned int* vpos, const unsigned int* vlist, const unsigned int* glist,
                  const unsigned int* gcount, const GroundParamsDev& p, PlaneDev* planes,
                  unsigned int* work, unsigned int* need_global, unsigned int* sensor_counts,
                  double* partial, std::size_t tiles_max, int blocks, cudaStream_t st) {
  if (p.local_planes) {
    needGlobalKernel<<<blocksFor(tiles_max, kThreads), kThreads, 0, st>>>(tile_begin, ntiles, vpos,
                                                                          need_global);
    GF_CUDA_CHECK_LAUNCH();
  }
  planesKernel<<<blocks, kPlaneThreads, 0, st>>>(xyz, sorted_keys, ybits, tile_begin, ntiles, vpos,
                                                 vlist, glist, gcount, need_global, sensor_counts,
                                                 p, planes, work);
  GF_CUDA_CHECK_LAUNCH();
  for (int pass = 0; pass < 3; ++pass) {
    globalRefineKernel<<<pass == 2 ? 1 : kRefineBlocks, kThreads, 0, st>>>(
        pass, xyz, glist, gcount, sensor_counts, p, planes, partial);
    GF_CUDA_CHECK_LAUNCH();
  }
}

void launchUnvoteOverhead(const float* xyz, std::uint8_t* voted, int n,
                          const normal::OverheadGrid& og, const GroundParamsDev& p,
                          unsigned int* sensor_counts, int* column_low, cudaStream_t st) {
  if (n <= 0) return;
  const unsigned int blocks = blocksFor(static_cast<std::size_t>(n), kThreads);
  if (p.sensor_check) {
    sensorBelowKernel<<<blocks, kThreads, 0, st>>>(xyz, voted, n, p, sensor_counts);
    GF_CUDA_CHECK_LAUNCH();
  }
  // 0x7f7f7f7f: an ordered int above every finite z.
  GF_CUDA_CHECK(
      cudaMemsetAsync(column_low, 0x7f, static_cast<std::size_t>(og.nx) * og.ny * sizeof(int), st));
  columnLowKernel<<<blocks, kThreads, 0, st>>>(xyz, voted, n, og, p, sensor_counts, column_low);
  GF_CUDA_CHECK_LAUNCH();
  unvoteOverheadKernel<<<blocks, kThreads, 0, st>>>(xyz, voted, n, og, p, sensor_counts,
                                                    column_low);
  GF_CUDA_CHECK_LAUNCH();
}

std::size_t refinePartialBytes() { return sizeof(double) * 10 * kRefineBlocks; }

}  // namespace cuda_impl
}  // namespace ground_filter
