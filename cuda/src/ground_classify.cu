// The distance test (see ground_classify.cuh).
#include <cmath>

#include "cuda_util.cuh"
#include "ground_classify.cuh"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

namespace {

// One block per tile: a tile can hold tens of thousands of points (an Ouster scan's no-return
// points at the origin), so wide blocks; 1024 threads measured 20 / 96 us against 57 / 321 us
// for 256 on a KITTI frame / the OS-128 scan (H200, Nsight Compute).
constexpr int kThreads = 1024;

using normal::kMinTilePoints;

__device__ inline double planeDistance(const PlaneDev& pl, const float* p) {
  return ((pl.n[0] * (p[0] - pl.o[0]) + pl.n[1] * (p[1] - pl.o[1])) + pl.n[2] * (p[2] - pl.o[2])) +
         pl.d;
}

/// Whether tile t is labelled against its own plane (the CPU's kOwnPlane): enough voted points
/// and its own fit found a plane.
__device__ inline bool ownPlane(const unsigned int* vpos, const unsigned int* tile_begin,
                                const PlaneDev* planes, unsigned int t) {
  return vpos[tile_begin[t + 1]] - vpos[tile_begin[t]] >= kMinTilePoints && planes[1 + t].valid;
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

/// The raised-tile test (CPU: PlaneStage::raisedTiles()), one thread per tile: donor[t] =
/// the neighbouring tile whose plane tile t is labelled against, -1 for its own.
__global__ void raisedTilesKernel(const unsigned long long* __restrict__ keys, int ybits,
                                  const unsigned int* __restrict__ tile_begin,
                                  const unsigned int* ntiles_dev,
                                  const unsigned int* __restrict__ vpos, const GroundParamsDev p,
                                  const PlaneDev* __restrict__ planes, double min_x, double min_y,
                                  double tile, int* __restrict__ donor) {
  const unsigned int ntiles = *ntiles_dev;
  const unsigned int t = blockIdx.x * blockDim.x + threadIdx.x;
  if (t >= ntiles) return;
  auto own = [&](unsigned int u) { return ownPlane(vpos, tile_begin, planes, u); };
  donor[t] = -1;
  if (!p.local_planes || !own(t)) return;
  const unsigned long long y_max = (1ull << ybits) - 1ull, key = keys[tile_begin[t]];
  const unsigned long long tx = key >> ybits, ty = key & y_max;
  const double cx = min_x + (static_cast<double>(tx) + 0.5) * tile;
  const double cy = min_y + (static_cast<double>(ty) + 0.5) * tile;
  const PlaneDev pt = planes[1 + t];
  const double zt = normal::planeZAt(pt.n, pt.d, pt.o, cx, cy);
  double zs[8];
  int who[8];
  int k = 0;
  auto key_at = [&](std::uint64_t i) { return static_cast<std::uint64_t>(keys[tile_begin[i]]); };
  for (int v = 0; v < 8; ++v) {
    std::uint64_t want;
    if (!normal::tileNeighbourKey(tx, ty, ybits, v, &want)) continue;
    const std::int64_t u = normal::findTile(key_at, ntiles, want);  // the tiles are in key order
    if (u < 0 || !own(static_cast<unsigned int>(u))) continue;
    const PlaneDev pu = planes[1 + u];
    zs[k] = normal::planeZAt(pu.n, pu.d, pu.o, cx, cy);
    who[k++] = static_cast<int>(u);
  }
  const int mid = normal::raisedTileMedian(zt, zs, k);
  if (mid >= 0) donor[t] = who[mid];
}

__global__ void __launch_bounds__(kThreads)
    classifyKernel(const float* __restrict__ xyz, const unsigned int* __restrict__ src,
                   const unsigned int* __restrict__ order, const std::uint8_t* __restrict__ voted,
                   const unsigned int* __restrict__ tile_begin, const unsigned int* ntiles_dev,
                   const unsigned int* __restrict__ vpos, const unsigned int* __restrict__ vlist,
                   const GroundParamsDev p, const PlaneDev* __restrict__ planes,
                   const int* __restrict__ donor, std::uint8_t* __restrict__ labels,
                   unsigned int* ground_count, unsigned int* work) {
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
    if (p.local_planes && ownPlane(vpos, tile_begin, planes, t)) {
      plane =
          planes[1 + (donor[t] >= 0 ? donor[t] : static_cast<int>(t))];  // raised: a neighbour's
    }
    if (!plane.valid) continue;  // uniform
    if (p.local_planes && m < kMinTilePoints && p.floor_share > 0.0) {
      // As the CPU (plane.cpp, sparse-tile floor): the cloud-wide plane moved to the tile's
      // lowest point when enough of the tile lies within plane_distance above it, within a
      // reach that grows with the distance from the sensor. Mins and count are exact, so the
      // order of the reduction does not matter.
      const double up = plane.n[2] < 0.0 ? -1.0 : 1.0;
      double low = HUGE_VAL, low_z = HUGE_VAL, near2 = p.sensor_check ? HUGE_VAL : 0.0;
      for (unsigned int j = b + threadIdx.x; j < e; j += blockDim.x) {
        const float* q = xyz + 3 * static_cast<std::size_t>(order[j]);
        low = fmin(low, up * planeDistance(plane, q));
        low_z = fmin(low_z, static_cast<double>(q[2]));
        if (p.sensor_check) {
          near2 = fmin(near2, normal::horizontalDistance2(p.sensor[0], p.sensor[1], q[0], q[1]));
        }
      }
      low = blockMin(low, floor_min_s);
      low_z = blockMin(low_z, floor_min_s);
      near2 = blockMin(near2, floor_min_s);
      const double reach =  // uniform: block-wide mins
          normal::floorReach(p.floor_max_shift, p.sensor_check, low_z, p.sensor[2], near2);
      if (low >= -reach && low <= reach) {  // uniform
        unsigned int on_floor = 0;
        for (unsigned int j = b + threadIdx.x; j < e; j += blockDim.x) {
          const double h = up * planeDistance(plane, xyz + 3 * static_cast<std::size_t>(order[j]));
          on_floor += h >= low && h <= low + p.plane_distance;
        }
        on_floor = blockSum(on_floor, floor_count_s);
        const double share = normal::floorShare(p.floor_share, p.floor_max_shift, low);
        if (static_cast<double>(on_floor) >= share * static_cast<double>(e - b)) {
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

void launchClassify(const float* xyz, const unsigned int* src, const unsigned int* order,
                    const std::uint8_t* voted, const unsigned int* tile_begin,
                    const unsigned int* ntiles, const unsigned int* vpos, const unsigned int* vlist,
                    const GroundParamsDev& p, const PlaneDev* planes, const int* donor,
                    std::uint8_t* labels, unsigned int* ground_count, unsigned int* work,
                    int blocks, cudaStream_t st) {
  classifyKernel<<<blocks, kThreads, 0, st>>>(xyz, src, order, voted, tile_begin, ntiles, vpos,
                                              vlist, p, planes, donor, labels, ground_count, work);
  GF_CUDA_CHECK_LAUNCH();
}

void launchRaisedTiles(const unsigned long long* sorted_keys, int ybits,
                       const unsigned int* tile_begin, const unsigned int* ntiles,
                       const unsigned int* vpos, const GroundParamsDev& p, const PlaneDev* planes,
                       double min_x, double min_y, double tile, int* donor, std::size_t tiles_max,
                       cudaStream_t st) {
  if (tiles_max == 0) return;
  const int threads = 256;
  const int blocks = static_cast<int>((tiles_max + threads - 1) / threads);
  raisedTilesKernel<<<blocks, threads, 0, st>>>(sorted_keys, ybits, tile_begin, ntiles, vpos, p,
                                                planes, min_x, min_y, tile, donor);
  GF_CUDA_CHECK_LAUNCH();
}

}  // namespace cuda_impl
}  // namespace ground_filter
