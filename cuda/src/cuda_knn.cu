// Exact K-nearest-neighbour search on the GPU over a hashed multi-level uniform grid.
//
// One search() (two streams: kernels, and downloads that overlap them):
//   upload -> bounds -> Morton keys (21 bits per axis over the bounding cube) -> radix sort ->
//   per-point "coarsest level at which this point starts a new cell" + histogram -> [sync: level
//   choice on the host] -> one hash table per level (cell key -> first point, count) -> one warp
//   per query, in chunks of Morton-ordered rows -> each chunk downloads while the next computes,
//   and the host scatters its rows to their original places.
// Sorting along the Morton curve makes every cell of every power-of-two level a contiguous range
// of the sorted points, so a single sort serves all levels. The lists stay on the device for
// neighborhoodPca() and countFlaggedNeighbors().

#include <cuda_runtime.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cub/device/device_radix_sort.cuh>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "ground_filter/cuda_knn.h"

namespace ground_filter {

namespace {

/// Throws CudaError naming the failed call and the CUDA error.
void checkCuda(cudaError_t err, const char* call, const char* file, int line) {
  if (err == cudaSuccess) return;
  std::ostringstream os;
  os << "CUDA error " << cudaGetErrorName(err) << " (" << cudaGetErrorString(err) << ") in " << call
     << " at " << file << ":" << line;
  throw CudaError(cudaGetErrorName(err), os.str());
}

}  // namespace

#define GF_CUDA_CHECK(call) ::ground_filter::checkCuda((call), #call, __FILE__, __LINE__)
// After a kernel launch: launch-configuration errors (asynchronous faults surface at the next
// synchronising call, which is checked too).
#define GF_CUDA_CHECK_LAUNCH() GF_CUDA_CHECK(cudaGetLastError())

namespace {

constexpr int kCoordBits = 21;  // per axis; 3 * 21 = 63-bit Morton keys
constexpr std::uint32_t kCoordMax = (1u << kCoordBits) - 1;
constexpr int kMaxLevels = kCoordBits + 1;  // level b has 2^b cells per axis, b = 0..21
constexpr unsigned long long kEmptyKey = ~0ull;
constexpr int kEmptyIndex = 0x7fffffff;  // sorts after every real index
constexpr int kWarp = 32;
constexpr int kQueryBlock = 128;  // 4 queries (warps) per block
// Register budget of the query kernel: 8 blocks (32 warps) per SM fit without spills; 12 blocks
// (40 registers, some spills) measured no faster on an H200.
constexpr int kQueryBlocksPerSm = 8;
constexpr int kStarveShells = 2;  // shells searched before a starving query moves a level up
// A query may use a level as fine as (bound radius) / kBoundCells: finer cells waste less on
// cells that straddle the bound's ball (isolated points next to dense regions), at the cost of
// more cell lookups.
constexpr float kBoundCells = 4.f;

/// One grid level: a hash table from Morton cell key to (first sorted point, point count).
struct LevelDesc {
  int bits;                      // 2^bits cells per axis
  float cell;                    // cell edge [m]
  unsigned int log2cap;          // table capacity = 2^log2cap slots
  unsigned long long table_off;  // first slot of this level in the shared slot arrays
};

/// Everything a query needs about the grid; passed by value (__grid_constant__).
struct GridDesc {
  float ox, oy, oz;  // grid origin (cloud minimum) [m]
  float inv;         // 2^21 / cube edge [1/m]
  float eps;         // conservative slack for float rounding in cell bounds [m]
  int nlev;          // levels, finest first
  int min_points;    // a query uses the finest level whose own cell holds >= this many points
  LevelDesc lv[kMaxLevels];
};

__host__ __device__ inline unsigned long long spreadBits(std::uint32_t v) {
  unsigned long long x = v & 0x1fffffu;
  x = (x | x << 32) & 0x1f00000000ffffull;
  x = (x | x << 16) & 0x1f0000ff0000ffull;
  x = (x | x << 8) & 0x100f00f00f00f00full;
  x = (x | x << 4) & 0x10c30c30c30c30c3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

__host__ __device__ inline unsigned long long morton(std::uint32_t x, std::uint32_t y,
                                                     std::uint32_t z) {
  return spreadBits(x) | (spreadBits(y) << 1) | (spreadBits(z) << 2);
}

/// Integer grid coordinate of `p` at the finest (21-bit) resolution; the same function is used for
/// the keys and the queries, so a point always finds its own cell.
__device__ inline std::uint32_t quantize(float p, float o, float inv) {
  float t = (p - o) * inv;
  t = fminf(fmaxf(t, 0.f), static_cast<float>(kCoordMax));
  return static_cast<std::uint32_t>(t);
}

__device__ inline unsigned int hashSlot(unsigned long long key, unsigned int log2cap) {
  // Fibonacci hashing; log2cap >= 5.
  return static_cast<unsigned int>((key * 0x9E3779B97F4A7C15ull) >> (64 - log2cap));
}

/// (first point, count) of cell `key` at `lv`, or (0, 0) when the cell is empty.
__device__ inline uint2 lookupCell(const unsigned long long* __restrict__ keys,
                                   const uint2* __restrict__ vals, const LevelDesc& lv,
                                   unsigned long long key) {
  const unsigned int mask = (1u << lv.log2cap) - 1u;
  unsigned int h = hashSlot(key, lv.log2cap);
  const unsigned long long* k = keys + lv.table_off;
  for (;;) {
    const unsigned long long s = __ldg(k + h);
    if (s == key) return __ldg(vals + lv.table_off + h);
    if (s == kEmptyKey) return make_uint2(0u, 0u);
    h = (h + 1u) & mask;
  }
}

/// Squared distance without FMA contraction: bit-identical to the CPU's (dx*dx + dy*dy) + dz*dz.
__device__ inline float sqDist(float ax, float ay, float az, float bx, float by, float bz) {
  const float dx = __fsub_rn(ax, bx), dy = __fsub_rn(ay, by), dz = __fsub_rn(az, bz);
  return __fadd_rn(__fadd_rn(__fmul_rn(dx, dx), __fmul_rn(dy, dy)), __fmul_rn(dz, dz));
}

/// (d, i) < (d2, i2) lexicographically: distance first, then index.
__device__ inline bool pairLess(float d, int i, float d2, int i2) {
  return d < d2 || (d == d2 && i < i2);
}

// ------------------------------------------------------------------ grid construction kernels

/// Order-preserving float <-> int mapping, so atomicMin/Max on ints give float min/max.
__device__ inline int floatToOrdered(float f) {
  const int i = __float_as_int(f);
  return i >= 0 ? i : i ^ 0x7fffffff;
}
__host__ __device__ inline float orderedToFloat(int i) {
#ifdef __CUDA_ARCH__
  return __int_as_float(i >= 0 ? i : i ^ 0x7fffffff);
#else
  const int b = i >= 0 ? i : i ^ 0x7fffffff;
  float f;
  std::memcpy(&f, &b, sizeof f);
  return f;
#endif
}

/// Bounds scratch: [0..2] min xyz, [3..5] max xyz (ordered ints), [6] non-finite point count.
__global__ void initBoundsKernel(int* b) {
  if (threadIdx.x < 3)
    b[threadIdx.x] = 0x7fffffff;
  else if (threadIdx.x < 6)
    b[threadIdx.x] = static_cast<int>(0x80000000u);
  else if (threadIdx.x == 6)
    b[6] = 0;
}

__global__ void boundsKernel(const float* __restrict__ xyz, int n, int* b) {
  float mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
  int bad = 0;
  for (int i = blockIdx.x * blockDim.x + threadIdx.x; i < n; i += gridDim.x * blockDim.x) {
    const float p[3] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
    if (!(isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]))) {
      ++bad;
      continue;
    }
    for (int a = 0; a < 3; ++a) {
      mn[a] = fminf(mn[a], p[a]);
      mx[a] = fmaxf(mx[a], p[a]);
    }
  }
  for (int o = 16; o > 0; o >>= 1) {
    for (int a = 0; a < 3; ++a) {
      mn[a] = fminf(mn[a], __shfl_xor_sync(0xffffffffu, mn[a], o));
      mx[a] = fmaxf(mx[a], __shfl_xor_sync(0xffffffffu, mx[a], o));
    }
    bad += __shfl_xor_sync(0xffffffffu, bad, o);
  }
  if ((threadIdx.x & 31) == 0) {
    for (int a = 0; a < 3; ++a) {
      if (mn[a] <= mx[a]) {
        atomicMin(&b[a], floatToOrdered(mn[a]));
        atomicMax(&b[3 + a], floatToOrdered(mx[a]));
      }
    }
    if (bad) atomicAdd(&b[6], bad);
  }
}

/// Grid frame from the bounds: frame[0..2] origin, [3] cube edge, [4] 2^21 / edge.
__global__ void frameKernel(const int* b, float* frame) {
  float lo[3], ext = 0.f;
  for (int a = 0; a < 3; ++a) {
    lo[a] = orderedToFloat(b[a]);
    const float hi = orderedToFloat(b[3 + a]);
    if (!(lo[a] <= hi))
      lo[a] = 0.f;  // no finite point at all
    else
      ext = fmaxf(ext, hi - lo[a]);
  }
  // A little over the extent so the maximum quantizes inside the grid; 1 m for a single point.
  const float edge = ext > 1e-20f ? ext * 1.0001f : 1.f;
  frame[0] = lo[0];
  frame[1] = lo[1];
  frame[2] = lo[2];
  frame[3] = edge;
  frame[4] = static_cast<float>(1u << kCoordBits) / edge;
}

__global__ void mortonKernel(const float* __restrict__ xyz, int n, const float* __restrict__ frame,
                             unsigned long long* keys, unsigned int* vals) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const float ox = frame[0], oy = frame[1], oz = frame[2], inv = frame[4];
  keys[i] = morton(quantize(xyz[3 * i], ox, inv), quantize(xyz[3 * i + 1], oy, inv),
                   quantize(xyz[3 * i + 2], oz, inv));
  vals[i] = static_cast<unsigned int>(i);
}

/// For sorted point i, the coarsest level b at which it starts a new cell (0 for the first point,
/// kMaxLevels when it shares its finest cell with point i-1); plus a histogram of those levels.
__global__ void cellStartLevelKernel(const unsigned long long* __restrict__ keys, int n,
                                     unsigned char* start_level, unsigned int* hist) {
  __shared__ unsigned int h[kMaxLevels + 1];
  if (threadIdx.x <= kMaxLevels) h[threadIdx.x] = 0;
  __syncthreads();
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) {
    int t = 0;
    if (i > 0) {
      const unsigned long long x = keys[i] ^ keys[i - 1];
      t = x == 0 ? kMaxLevels : kCoordBits - (63 - __clzll(static_cast<long long>(x))) / 3;
    }
    start_level[i] = static_cast<unsigned char>(t);
    atomicAdd(&h[t], 1u);
  }
  __syncthreads();
  if (threadIdx.x <= kMaxLevels && h[threadIdx.x]) atomicAdd(&hist[threadIdx.x], h[threadIdx.x]);
}

/// Sorted points with their original index in w (as int bits).
__global__ void gatherKernel(const float* __restrict__ xyz, const unsigned int* __restrict__ order,
                             int n, float4* sorted) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const unsigned int j = order[i];
  sorted[i] =
      make_float4(xyz[3 * j], xyz[3 * j + 1], xyz[3 * j + 2], __int_as_float(static_cast<int>(j)));
}

/// Inserts every cell of every level: thread i inserts the cells that start at sorted point i.
__global__ void insertCellsKernel(const __grid_constant__ GridDesc g,
                                  const unsigned long long* __restrict__ keys,
                                  const unsigned char* __restrict__ start_level, int n,
                                  unsigned long long* table_keys, uint2* table_vals) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const int t = start_level[i];
  const unsigned long long key = keys[i];
  for (int l = 0; l < g.nlev; ++l) {
    const LevelDesc& lv = g.lv[l];
    if (lv.bits < t) break;  // levels are finest first: coarser ones do not start here either
    const unsigned long long ck = key >> (3 * (kCoordBits - lv.bits));
    const unsigned int mask = (1u << lv.log2cap) - 1u;
    unsigned int h = hashSlot(ck, lv.log2cap);
    for (;;) {
      const unsigned long long prev = atomicCAS(&table_keys[lv.table_off + h], kEmptyKey, ck);
      if (prev == kEmptyKey || prev == ck) break;
      h = (h + 1u) & mask;
    }
    table_vals[lv.table_off + h].x = static_cast<unsigned int>(i);
  }
}

/// Sets each cell's point count: thread i closes the cells that end at sorted point i.
__global__ void closeCellsKernel(const __grid_constant__ GridDesc g,
                                 const unsigned long long* __restrict__ keys,
                                 const unsigned char* __restrict__ start_level, int n,
                                 const unsigned long long* __restrict__ table_keys,
                                 uint2* table_vals) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const int t_next = i + 1 < n ? start_level[i + 1] : 0;  // the last point closes every level
  const unsigned long long key = keys[i];
  for (int l = 0; l < g.nlev; ++l) {
    const LevelDesc& lv = g.lv[l];
    if (lv.bits < t_next) break;
    const unsigned long long ck = key >> (3 * (kCoordBits - lv.bits));
    const unsigned int mask = (1u << lv.log2cap) - 1u;
    unsigned int h = hashSlot(ck, lv.log2cap);
    while (table_keys[lv.table_off + h] != ck) h = (h + 1u) & mask;
    table_vals[lv.table_off + h].y =
        static_cast<unsigned int>(i + 1) - table_vals[lv.table_off + h].x;
  }
}

// ------------------------------------------------------------------ the query kernel

/// Per-query work counters (CudaKnnOptions::collect_stats).
enum Stat {
  kStatCandidates,
  kStatInsertions,
  kStatShells,
  kStatLevels,
  kStatMaxCycles,
  kStatCycles,
  kStatOver100k,
  kStatOver1M,
  kStatSlowCand,
  kStatSlowIns,
  kStatSlowShells,
  kStatSlowLevels,
  kStatSlowBits,
  kStatSlowLim,
  kStatSlowKd,
  kStatCount
};

/// The warp's sorted top-K list: lane l holds slots l and l + 32.
struct WarpList {
  float dlo, dhi;
  int ilo, ihi;
  float kd;  // K-th slot (broadcast)
  int ki;
};

template <bool kTwoHalves>
__device__ inline void warpInsert(WarpList& w, float d, int id, int lane, int k) {
  const unsigned full = 0xffffffffu;
  int pos = __popc(__ballot_sync(full, pairLess(w.dlo, w.ilo, d, id)));
  float phi = 0.f;
  int pihi = 0;
  if (kTwoHalves) {
    pos += __popc(__ballot_sync(full, pairLess(w.dhi, w.ihi, d, id)));
    const float last_d = __shfl_sync(full, w.dlo, 31);
    const int last_i = __shfl_sync(full, w.ilo, 31);
    phi = __shfl_up_sync(full, w.dhi, 1);
    pihi = __shfl_up_sync(full, w.ihi, 1);
    if (lane == 0) {
      phi = last_d;
      pihi = last_i;
    }
  }
  const float plo = __shfl_up_sync(full, w.dlo, 1);
  const int pilo = __shfl_up_sync(full, w.ilo, 1);
  if (lane > pos) {
    w.dlo = plo;
    w.ilo = pilo;
  } else if (lane == pos) {
    w.dlo = d;
    w.ilo = id;
  }
  if (kTwoHalves) {
    if (lane + 32 > pos) {
      w.dhi = phi;
      w.ihi = pihi;
    } else if (lane + 32 == pos) {
      w.dhi = d;
      w.ihi = id;
    }
  }
  const int kl = (k - 1) & 31;
  if (!kTwoHalves || k <= 32) {
    w.kd = __shfl_sync(full, w.dlo, kl);
    w.ki = __shfl_sync(full, w.ilo, kl);
  } else {
    w.kd = __shfl_sync(full, w.dhi, kl);
    w.ki = __shfl_sync(full, w.ihi, kl);
  }
}

/// Bitonic sort of one (key, cell) pair per lane by increasing key, across the warp.
__device__ inline void warpSortCells(float& key, uint2& cell, int lane) {
  const unsigned full = 0xffffffffu;
  for (int size = 2; size <= 32; size <<= 1) {
    for (int stride = size >> 1; stride > 0; stride >>= 1) {
      const float ok = __shfl_xor_sync(full, key, stride);
      const unsigned ox = __shfl_xor_sync(full, cell.x, stride);
      const unsigned oy = __shfl_xor_sync(full, cell.y, stride);
      const bool ascending = (lane & size) == 0 || size == 32;
      const bool lower = (lane & stride) == 0;
      if (lower == ascending ? ok < key : ok > key) {
        key = ok;
        cell = make_uint2(ox, oy);
      }
    }
  }
}

/// Largest squared distance from q to the k points of sorted positions [w0, w0 + k), warp-wide.
__device__ inline float windowMax(const float4* __restrict__ pts, long long w0, int k,
                                  const float4& q, int lane) {
  float dmax = 0.f;
  if (lane < k) {
    const float4 p = pts[w0 + lane];
    dmax = sqDist(p.x, p.y, p.z, q.x, q.y, q.z);
  }
  if (lane + 32 < k) {
    const float4 p = pts[w0 + lane + 32];
    dmax = fmaxf(dmax, sqDist(p.x, p.y, p.z, q.x, q.y, q.z));
  }
  for (int o = 16; o > 0; o >>= 1) dmax = fmaxf(dmax, __shfl_xor_sync(0xffffffffu, dmax, o));
  return dmax;
}

/// Bitonic sort of one (distance, index) pair per lane by increasing (distance, index).
__device__ inline void warpSortPairs(float& d, int& id, int lane) {
  const unsigned full = 0xffffffffu;
  for (int size = 2; size <= 32; size <<= 1) {
    for (int stride = size >> 1; stride > 0; stride >>= 1) {
      const float od = __shfl_xor_sync(full, d, stride);
      const int oi = __shfl_xor_sync(full, id, stride);
      const bool ascending = (lane & size) == 0 || size == 32;
      const bool lower = (lane & stride) == 0;
      if (lower == ascending ? pairLess(od, oi, d, id) : pairLess(d, id, od, oi)) {
        d = od;
        id = oi;
      }
    }
  }
}

/// One warp per query; queries [base, end) of the Morton-sorted points; row s of the output holds
/// the list of sorted point s (original indices). kTwoHalves: k > 32. kSortCells: visit the cells
/// of each batch nearest first (the K-th distance shrinks sooner, fewer insertions).
template <bool kTwoHalves, bool kSortCells>
__global__ void __launch_bounds__(kQueryBlock, kQueryBlocksPerSm)
    knnKernel(const __grid_constant__ GridDesc g, const float4* __restrict__ pts,
              const unsigned long long* __restrict__ tkeys, const uint2* __restrict__ tvals, int n,
              int base, int end, int k, std::int32_t* __restrict__ out_idx,
              float* __restrict__ out_d2, unsigned long long* __restrict__ stats) {
  const unsigned full = 0xffffffffu;
  const int lane = threadIdx.x & 31;
  const long long qi =
      base + ((static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x) >> 5);
  if (qi >= end) return;  // uniform per warp
  const long long t_start = stats ? clock64() : 0;
  unsigned int n_cand = 0, n_ins = 0, n_shell = 0, n_lev = 0;
  const float4 q = pts[qi];
  const std::uint32_t qx = quantize(q.x, g.ox, g.inv), qy = quantize(q.y, g.oy, g.inv),
                      qz = quantize(q.z, g.oz, g.inv);

  // Upper bound `lim` of the K-th squared distance: any k points bound it. Here the k points
  // before q and the k points from q on in Morton order, whichever is closer: where the curve
  // jumps far on one side of q, the other side still gives a tight bound. Candidates and cells
  // beyond the bound are skipped from the start.
  float lim = INFINITY;
  if (n >= k) {
    const long long lo = max(qi - k + 1, 0ll), hi = min(qi, static_cast<long long>(n - k));
    lim = fminf(windowMax(pts, lo, k, q, lane), windowMax(pts, hi, k, q, lane));
  }
  // Level: the finest whose own cell holds >= min_points points, or, if finer, the finest whose
  // cells are at least the bound's radius / kBoundCells (the k window points then lie within
  // kBoundCells + 1 shells).
  // The second rule keeps isolated points from landing on a coarse level whose shells hold a
  // large part of the cloud. Lanes test one level each.
  bool ok = false, ok_r = false;
  if (lane < g.nlev) {
    const LevelDesc& lv = g.lv[lane];
    const int s = kCoordBits - lv.bits;
    const uint2 c = lookupCell(tkeys, tvals, lv, morton(qx >> s, qy >> s, qz >> s));
    ok = static_cast<int>(c.y) >= g.min_points;
    ok_r = kBoundCells * lv.cell >= sqrtf(lim);
  }
  const unsigned okm = __ballot_sync(full, ok), okr = __ballot_sync(full, ok_r);
  int li = min(okm ? __ffs(okm) - 1 : g.nlev - 1, okr ? __ffs(okr) - 1 : g.nlev - 1);

  WarpList w;
  for (;;) {  // one pass per level tried; a pass that starves moves to the next coarser level
    ++n_lev;
    const LevelDesc& lv = g.lv[li];
    const int shift = kCoordBits - lv.bits;
    const int cx = static_cast<int>(qx >> shift), cy = static_cast<int>(qy >> shift),
              cz = static_cast<int>(qz >> shift);
    const int last = (1 << lv.bits) - 1;
    const float cs = lv.cell, eps = g.eps;
    // Cell index of coordinate v clamped to [-2, last + 2] (no int overflow for huge radii).
    auto cellOf = [&](float v, float o) {
      return static_cast<int>(
          fminf(fmaxf(floorf((v - o) / cs), -2.f), static_cast<float>(last + 2)));
    };
    w.dlo = w.dhi = w.kd = INFINITY;
    w.ilo = w.ihi = w.ki = kEmptyIndex;
    bool restart = false;

    for (int r = 0;; ++r) {
      ++n_shell;
      int x0 = max(cx - r, 0), x1 = min(cx + r, last);
      int y0 = max(cy - r, 0), y1 = min(cy + r, last);
      int z0 = max(cz - r, 0), z1 = min(cz + r, last);
      const float reach = fminf(w.kd, lim);  // squared distance a useful point can have
      if (reach < INFINITY) {                // only cells that can hold a point within it
        const float rad = sqrtf(reach) + eps;
        x0 = max(x0, cellOf(q.x - rad, g.ox) - 1);
        x1 = min(x1, cellOf(q.x + rad, g.ox) + 1);
        y0 = max(y0, cellOf(q.y - rad, g.oy) - 1);
        y1 = min(y1, cellOf(q.y + rad, g.oy) + 1);
        z0 = max(z0, cellOf(q.z - rad, g.oz) - 1);
        z1 = min(z1, cellOf(q.z + rad, g.oz) + 1);
      }
      const int nx = x1 - x0 + 1, ny = y1 - y0 + 1, nz = z1 - z0 + 1;
      const int total = (nx > 0 && ny > 0 && nz > 0) ? nx * ny * nz : 0;
      for (int cbase = 0; cbase < total; cbase += kWarp) {
        // Each lane looks up one cell of the shell.
        uint2 cell = make_uint2(0u, 0u);
        float key = INFINITY;
        const int t = cbase + lane;
        if (t < total) {
          const int ix = x0 + t % nx, iy = y0 + (t / nx) % ny, iz = z0 + t / (nx * ny);
          const int cheb = max(max(abs(ix - cx), abs(iy - cy)), abs(iz - cz));
          if (cheb == r) {
            const float lx = g.ox + ix * cs, ly = g.oy + iy * cs, lz = g.oz + iz * cs;
            const float ex = fmaxf(fmaxf(lx - q.x, q.x - (lx + cs)) - eps, 0.f);
            const float ey = fmaxf(fmaxf(ly - q.y, q.y - (ly + cs)) - eps, 0.f);
            const float ez = fmaxf(fmaxf(lz - q.z, q.z - (lz + cs)) - eps, 0.f);
            const float box = ex * ex + ey * ey + ez * ez;
            if (box <= fminf(w.kd, lim)) {
              cell =
                  lookupCell(tkeys, tvals, lv,
                             morton(static_cast<std::uint32_t>(ix), static_cast<std::uint32_t>(iy),
                                    static_cast<std::uint32_t>(iz)));
              if (cell.y) key = box;
            }
          }
        }
        if (kSortCells) warpSortCells(key, cell, lane);
        // Concatenate the cells' point ranges across the warp.
        unsigned int incl = cell.y;
        for (int o = 1; o < kWarp; o <<= 1) {
          const unsigned int v = __shfl_up_sync(full, incl, o);
          if (lane >= o) incl += v;
        }
        const unsigned int excl = incl - cell.y;
        const unsigned int count = __shfl_sync(full, incl, 31);
        n_cand += count;
        for (unsigned int cb = 0; cb < count; cb += kWarp) {
          const unsigned int gpos = cb + lane;
          int owner = 0;  // first lane whose inclusive sum exceeds gpos
          for (int step = 16; step > 0; step >>= 1) {
            const unsigned int v = __shfl_sync(full, incl, owner + step - 1);
            if (v <= gpos) owner += step;
          }
          const unsigned int ostart = __shfl_sync(full, cell.x, owner);
          const unsigned int oexcl = __shfl_sync(full, excl, owner);
          float d = INFINITY;
          int id = kEmptyIndex;
          const bool valid = gpos < count;
          if (valid) {
            const float4 p = pts[ostart + (gpos - oexcl)];
            d = sqDist(p.x, p.y, p.z, q.x, q.y, q.z);
            id = __float_as_int(p.w);
          }
          const bool useful = valid && d <= lim;
          unsigned m = __ballot_sync(full, useful && pairLess(d, id, w.kd, w.ki));
          if (__popc(m) > 1 && __shfl_sync(full, w.ilo, 0) == kEmptyIndex) {
            // Empty list: the batch, sorted, becomes the list (saves one insertion per point).
            float sd = useful ? d : INFINITY;
            int si = useful ? id : kEmptyIndex;
            warpSortPairs(sd, si, lane);
            w.dlo = sd;
            w.ilo = si;
            const int kl = (k - 1) & 31;
            w.kd = (!kTwoHalves || k <= 32) ? __shfl_sync(full, w.dlo, kl) : INFINITY;
            w.ki = (!kTwoHalves || k <= 32) ? __shfl_sync(full, w.ilo, kl) : kEmptyIndex;
            n_ins += __popc(m);
            m = 0;
          }
          while (m) {
            const int src = __ffs(m) - 1;
            const float dd = __shfl_sync(full, d, src);
            const int ii = __shfl_sync(full, id, src);
            warpInsert<kTwoHalves>(w, dd, ii, lane, k);
            ++n_ins;
            m &= ~(1u << src);
            m &= __ballot_sync(full, useful && pairLess(d, id, w.kd, w.ki));
          }
        }
      }
      // Distance from q to the outside of the visited block of cells (grid edges excluded).
      float bound = INFINITY;
      if (cx - r > 0) bound = fminf(bound, q.x - (g.ox + (cx - r) * cs));
      if (cx + r < last) bound = fminf(bound, g.ox + (cx + r + 1) * cs - q.x);
      if (cy - r > 0) bound = fminf(bound, q.y - (g.oy + (cy - r) * cs));
      if (cy + r < last) bound = fminf(bound, g.oy + (cy + r + 1) * cs - q.y);
      if (cz - r > 0) bound = fminf(bound, q.z - (g.oz + (cz - r) * cs));
      if (cz + r < last) bound = fminf(bound, g.oz + (cz + r + 1) * cs - q.z);
      if (bound == INFINITY) break;  // the block covers the whole grid
      bound -= eps;
      if (w.ki != kEmptyIndex && bound > 0.f && w.kd <= bound * bound) break;
      // Still short of k points two shells out while the bound's ball needs many more shells:
      // this level is too fine around q; start again one level coarser rather than walking many
      // empty shells.
      if (w.ki == kEmptyIndex && r >= kStarveShells && !(sqrtf(lim) <= (kBoundCells + 1) * cs) &&
          li + 1 < g.nlev) {
        restart = true;
        break;
      }
    }
    if (!restart) break;
    ++li;
  }

  const std::size_t row = static_cast<std::size_t>(qi) * k;
  if (lane < k) {
    out_idx[row + lane] = w.ilo == kEmptyIndex ? -1 : w.ilo;
    if (out_d2) out_d2[row + lane] = w.ilo == kEmptyIndex ? INFINITY : w.dlo;
  }
  if (kTwoHalves && lane + 32 < k) {
    out_idx[row + lane + 32] = w.ihi == kEmptyIndex ? -1 : w.ihi;
    if (out_d2) out_d2[row + lane + 32] = w.ihi == kEmptyIndex ? INFINITY : w.dhi;
  }
  if (stats && lane == 0) {
    const unsigned long long cyc = static_cast<unsigned long long>(clock64() - t_start);
    atomicAdd(&stats[kStatCandidates], n_cand);
    atomicAdd(&stats[kStatInsertions], n_ins);
    atomicAdd(&stats[kStatShells], n_shell);
    atomicAdd(&stats[kStatLevels], n_lev);
    atomicAdd(&stats[kStatCycles], cyc);
    if (cyc > 100000) atomicAdd(&stats[kStatOver100k], 1ull);
    if (cyc > 1000000) atomicAdd(&stats[kStatOver1M], 1ull);
    if (atomicMax(&stats[kStatMaxCycles], cyc) < cyc) {  // the slowest so far (racy: diagnostics)
      stats[kStatSlowCand] = n_cand;
      stats[kStatSlowIns] = n_ins;
      stats[kStatSlowShells] = n_shell;
      stats[kStatSlowLevels] = n_lev;
      stats[kStatSlowBits] = g.lv[li].bits;
      stats[kStatSlowLim] = __float_as_uint(lim);
      stats[kStatSlowKd] = __float_as_uint(w.kd);
    }
  }
}

// ------------------------------------------------------------------ neighbourhood PCA
// Mirrors the core's computeNeighborhoodPca(): mean relative to the query point and centred
// covariance in double, then Eigen's closed-form 3x3 solver (SelfAdjointEigenSolver::computeDirect,
// Eigen 3.4) step by step, so both give the same normal and eigenvalues up to rounding (the
// library is built without FMA contraction; sqrt/atan2/cos/sin differ in the last bits at most).

constexpr double kDblEps = 2.220446049250313e-16;  // NumTraits<double>::epsilon()

__device__ inline void cross3(const double a[3], const double b[3], double c[3]) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

__device__ inline double sqNorm3(const double a[3]) {
  return a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
}

/// Eigen's extract_kernel: unit vector spanning the kernel of the rank-2 matrix `m`.
__device__ inline void extractKernel(const double m[3][3], double res[3], double rep[3]) {
  int i0 = 0;
  double best = fabs(m[0][0]);
  if (fabs(m[1][1]) > best) {
    i0 = 1;
    best = fabs(m[1][1]);
  }
  if (fabs(m[2][2]) > best) i0 = 2;
  const int i1 = (i0 + 1) % 3, i2 = (i0 + 2) % 3;
  for (int r = 0; r < 3; ++r) rep[r] = m[r][i0];
  const double a[3] = {m[0][i1], m[1][i1], m[2][i1]}, b[3] = {m[0][i2], m[1][i2], m[2][i2]};
  double c0[3], c1[3];
  cross3(rep, a, c0);
  cross3(rep, b, c1);
  const double n0 = sqNorm3(c0), n1 = sqNorm3(c1);
  if (n0 > n1) {
    const double s = sqrt(n0);
    for (int r = 0; r < 3; ++r) res[r] = c0[r] / s;
  } else {
    const double s = sqrt(n1);
    for (int r = 0; r < 3; ++r) res[r] = c1[r] / s;
  }
}

/// Eigen's computeDirect for a symmetric 3x3 matrix: ascending eigenvalues and the eigenvector of
/// the smallest one (column 0).
__device__ void eigenDirect3(const double a[3][3], double ev[3], double v0[3]) {
  const double shift = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
  double s[3][3];
  double scale = 0.0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      s[r][c] = a[r][c] - (r == c ? shift : 0.0);
      scale = fmax(scale, fabs(s[r][c]));
    }
  }
  if (scale > 0.0) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) s[r][c] /= scale;
    }
  }
  // computeRoots
  {
    const double inv3 = 1.0 / 3.0, sqrt3 = sqrt(3.0);
    const double c0 = s[0][0] * s[1][1] * s[2][2] + 2.0 * s[1][0] * s[2][0] * s[2][1] -
                      s[0][0] * s[2][1] * s[2][1] - s[1][1] * s[2][0] * s[2][0] -
                      s[2][2] * s[1][0] * s[1][0];
    const double c1 = s[0][0] * s[1][1] - s[1][0] * s[1][0] + s[0][0] * s[2][2] -
                      s[2][0] * s[2][0] + s[1][1] * s[2][2] - s[2][1] * s[2][1];
    const double c2 = s[0][0] + s[1][1] + s[2][2];
    const double c2_over_3 = c2 * inv3;
    double a_over_3 = (c2 * c2_over_3 - c1) * inv3;
    a_over_3 = a_over_3 > 0.0 ? a_over_3 : 0.0;
    const double half_b = 0.5 * (c0 + c2_over_3 * (2.0 * c2_over_3 * c2_over_3 - c1));
    double qq = a_over_3 * a_over_3 * a_over_3 - half_b * half_b;
    qq = qq > 0.0 ? qq : 0.0;
    const double rho = sqrt(a_over_3);
    const double theta = atan2(sqrt(qq), half_b) * inv3;
    const double cos_t = cos(theta), sin_t = sin(theta);
    ev[0] = c2_over_3 - rho * (cos_t + sqrt3 * sin_t);
    ev[1] = c2_over_3 - rho * (cos_t - sqrt3 * sin_t);
    ev[2] = c2_over_3 + 2.0 * rho * cos_t;
  }
  if (ev[2] - ev[0] <= kDblEps) {
    v0[0] = 1.0;
    v0[1] = v0[2] = 0.0;
  } else {
    double d0 = ev[2] - ev[1];
    const double d1 = ev[1] - ev[0];
    int k = 0, l = 2;
    if (d0 > d1) {
      k = 2;
      l = 0;
      d0 = d1;
    }
    double tmp[3][3];
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) tmp[r][c] = s[r][c] - (r == c ? ev[k] : 0.0);
    }
    double vk[3], vl[3];
    extractKernel(tmp, vk, vl);
    if (k == 0) {
      for (int r = 0; r < 3; ++r) v0[r] = vk[r];
    } else {
      if (d0 <= 2.0 * kDblEps * d1) {
        const double dot = vk[0] * vl[0] + vk[1] * vl[1] + vk[2] * vl[2];
        for (int r = 0; r < 3; ++r) vl[r] -= dot * vl[r];  // sic (Eigen 3.4)
        const double z = sqNorm3(vl);
        if (z > 0.0) {
          const double sz = sqrt(z);
          for (int r = 0; r < 3; ++r) vl[r] /= sz;
        }
      } else {
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) tmp[r][c] = s[r][c] - (r == c ? ev[l] : 0.0);
        }
        double dummy[3];
        extractKernel(tmp, vl, dummy);
      }
      for (int r = 0; r < 3; ++r) v0[r] = vl[r];
    }
  }
  for (int r = 0; r < 3; ++r) {
    ev[r] *= scale;
    ev[r] += shift;
  }
}

/// PCA of sorted row s, written at the point's original index: normal (3), eigenvalues ascending
/// divided by their sum (3), valid.
__global__ void pcaKernel(const float* __restrict__ xyz, const float4* __restrict__ pts,
                          const std::int32_t* __restrict__ rows, int n, int k,
                          float* __restrict__ normals, float* __restrict__ eigen,
                          std::uint8_t* __restrict__ valid) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= n) return;
  const float4 qp = pts[s];
  const int orig = __float_as_int(qp.w);
  const std::int32_t* row = rows + static_cast<std::size_t>(s) * k;
  const double ox = qp.x, oy = qp.y, oz = qp.z;
  double mx = 0.0, my = 0.0, mz = 0.0;
  int m = 0;
  for (; m < k; ++m) {
    const int j = row[m];
    if (j < 0) break;
    mx += static_cast<double>(xyz[3 * j]) - ox;
    my += static_cast<double>(xyz[3 * j + 1]) - oy;
    mz += static_cast<double>(xyz[3 * j + 2]) - oz;
  }
  bool ok = false;
  double nv[3] = {0.0, 0.0, 0.0}, ev[3] = {0.0, 0.0, 0.0};
  if (m >= 3) {
    mx /= m;
    my /= m;
    mz /= m;
    double cxx = 0, cxy = 0, cxz = 0, cyy = 0, cyz = 0, czz = 0;
    for (int j = 0; j < m; ++j) {
      const int p = row[j];
      const double dx = static_cast<double>(xyz[3 * p]) - ox - mx;
      const double dy = static_cast<double>(xyz[3 * p + 1]) - oy - my;
      const double dz = static_cast<double>(xyz[3 * p + 2]) - oz - mz;
      cxx += dx * dx;
      cxy += dx * dy;
      cxz += dx * dz;
      cyy += dy * dy;
      cyz += dy * dz;
      czz += dz * dz;
    }
    const double trace = cxx + cyy + czz;
    if (trace > 1e-12 * m) {
      const double dm = m;
      const double cov[3][3] = {{cxx / dm, cxy / dm, cxz / dm},
                                {cxy / dm, cyy / dm, cyz / dm},
                                {cxz / dm, cyz / dm, czz / dm}};
      eigenDirect3(cov, ev, nv);
      for (int r = 0; r < 3; ++r) ev[r] = ev[r] < 0.0 ? 0.0 : ev[r];  // cwiseMax(0)
      const double sum = ev[0] + ev[1] + ev[2];
      if (sum > 0.0) {
        for (int r = 0; r < 3; ++r) ev[r] /= sum;
        ok = isfinite(nv[0]) && isfinite(nv[1]) && isfinite(nv[2]);
      }
    }
  }
  for (int r = 0; r < 3; ++r) {
    normals[3 * static_cast<std::size_t>(orig) + r] = ok ? static_cast<float>(nv[r]) : 0.f;
    eigen[3 * static_cast<std::size_t>(orig) + r] = ok ? static_cast<float>(ev[r]) : 0.f;
  }
  valid[orig] = ok;
}

/// For sorted row s: neighbours whose flag is set, and valid neighbours; at the original index.
__global__ void countKernel(const float4* __restrict__ pts, const std::int32_t* __restrict__ rows,
                            int n, int k, const std::uint8_t* __restrict__ flags,
                            std::uint16_t* __restrict__ flagged,
                            std::uint16_t* __restrict__ neighbors) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= n) return;
  const std::int32_t* row = rows + static_cast<std::size_t>(s) * k;
  int m = 0, u = 0;
  for (; m < k; ++m) {
    const int j = row[m];
    if (j < 0) break;
    u += flags[j] != 0;
  }
  const int orig = __float_as_int(pts[s].w);
  flagged[orig] = static_cast<std::uint16_t>(u);
  neighbors[orig] = static_cast<std::uint16_t>(m);
}

/// Start-up probe: proves that this build's device code runs on the device.
__global__ void probeKernel(int* out) { *out = 42; }

// ------------------------------------------------------------------ host helpers

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

unsigned int blocksFor(std::size_t n, int threads) {
  return static_cast<unsigned int>((n + threads - 1) / threads);
}

/// Device buffer that only grows (with 1/8 slack, so slowly growing scans do not reallocate).
struct DeviceBuffer {
  void* ptr = nullptr;
  std::size_t bytes = 0;
  ~DeviceBuffer() {
    if (ptr) cudaFree(ptr);  // no throwing from a destructor
  }
  void ensure(std::size_t need, std::size_t* total) {
    if (need <= bytes) return;
    if (ptr) {
      GF_CUDA_CHECK(cudaFree(ptr));
      *total -= bytes;
      ptr = nullptr;
      bytes = 0;
    }
    const std::size_t want = need + need / 8;
    GF_CUDA_CHECK(cudaMalloc(&ptr, want));
    bytes = want;
    *total += want;
  }
  template <class T>
  T* as() const {
    return static_cast<T*>(ptr);
  }
};

/// Pinned host buffer that only grows.
struct PinnedBuffer {
  void* ptr = nullptr;
  std::size_t bytes = 0;
  ~PinnedBuffer() {
    if (ptr) cudaFreeHost(ptr);
  }
  void ensure(std::size_t need) {
    if (need <= bytes) return;
    if (ptr) {
      GF_CUDA_CHECK(cudaFreeHost(ptr));
      ptr = nullptr;
      bytes = 0;
    }
    const std::size_t want = need + need / 8;
    GF_CUDA_CHECK(cudaMallocHost(&ptr, want));
    bytes = want;
  }
  template <class T>
  T* as() const {
    return static_cast<T*>(ptr);
  }
};

/// memcpy over all cores for large blocks (one core copies far slower than PCIe delivers).
void parallelCopy(void* dst, const void* src, std::size_t bytes) {
  constexpr std::size_t kSlice = 1u << 20;
  if (bytes < 2 * kSlice) {
    std::memcpy(dst, src, bytes);
    return;
  }
  const std::int64_t slices = static_cast<std::int64_t>((bytes + kSlice - 1) / kSlice);
#pragma omp parallel for schedule(static)
  for (std::int64_t s = 0; s < slices; ++s) {
    const std::size_t b = static_cast<std::size_t>(s) * kSlice;
    std::memcpy(static_cast<char*>(dst) + b, static_cast<const char*>(src) + b,
                std::min(kSlice, bytes - b));
  }
}

}  // namespace

// ------------------------------------------------------------------ CudaKnn

struct CudaKnn::Impl {
  static constexpr int kMaxChunks = 16;
  CudaKnnOptions opt;
  cudaStream_t stream = nullptr;  // all kernels
  cudaStream_t copy = nullptr;    // result downloads, overlapping the next query chunk
  cudaEvent_t kernel_done[kMaxChunks] = {};
  cudaEvent_t copy_done[kMaxChunks] = {};
  cudaEvent_t order_done = nullptr;
  std::string device_name;
  std::size_t device_bytes = 0;
  CudaKnnTimings timings;
  // The lists of the last search, kept on the device (rows in Morton order).
  std::size_t list_n = 0;
  int list_k = 0;

  DeviceBuffer xyz, keys_a, keys_b, vals_a, vals_b, start_level, sorted, sort_temp, small,
      table_keys, table_vals, out_idx, out_d2, pca, flags, counts;
  PinnedBuffer h_small, h_xyz, h_idx, h_d2, h_order, h_pca, h_flags, h_counts;

  /// Device bytes still allowed: the explicit limit, or 90 % of what is free now.
  std::size_t allowance() const {
    if (opt.memory_limit > 0) {
      return opt.memory_limit > device_bytes ? opt.memory_limit - device_bytes : 0;
    }
    std::size_t free_b = 0, total_b = 0;
    GF_CUDA_CHECK(cudaMemGetInfo(&free_b, &total_b));
    return free_b / 10 * 9;
  }

  /// Grows `buf` to `need` bytes unless that breaks the memory limit.
  void grow(DeviceBuffer& buf, std::size_t need, const char* what) {
    if (need <= buf.bytes) return;
    const std::size_t extra = need + need / 8 - buf.bytes;
    if (opt.memory_limit > 0 && device_bytes + extra > opt.memory_limit) {
      std::ostringstream os;
      os << "CudaKnn: " << what << " needs " << (extra >> 20) << " MiB more device memory; the "
         << "memory limit is " << (opt.memory_limit >> 20) << " MiB (" << (device_bytes >> 20)
         << " MiB held)";
      throw CudaError("cudaErrorMemoryAllocation", os.str());
    }
    buf.ensure(need, &device_bytes);
  }

  void requireLists(const char* what) const {
    if (list_n == 0) {
      throw std::logic_error(std::string("CudaKnn::") + what +
                             ": no neighbour lists on the device (no successful search yet)");
    }
  }
};

bool CudaKnn::deviceAvailable(std::string* why, int device) {
  int count = 0;
  cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess) {
    if (why) *why = std::string(cudaGetErrorName(err)) + ": " + cudaGetErrorString(err);
    cudaGetLastError();  // clear
    return false;
  }
  if (device < 0 || device >= count) {
    if (why) {
      *why = "cudaErrorInvalidDevice: device " + std::to_string(device) + " requested, " +
             std::to_string(count) + " present";
    }
    return false;
  }
  cudaDeviceProp prop;
  err = cudaGetDeviceProperties(&prop, device);
  if (err != cudaSuccess) {
    if (why) *why = std::string(cudaGetErrorName(err)) + ": " + cudaGetErrorString(err);
    cudaGetLastError();
    return false;
  }
  if (prop.major * 10 + prop.minor < 75) {
    if (why) {
      *why = "cudaErrorNoKernelImageForDevice: " + std::string(prop.name) + " is sm_" +
             std::to_string(prop.major * 10 + prop.minor) + ", this build needs sm_75 or newer";
    }
    return false;
  }
  // Run a kernel: catches a device this build has no code for, or a broken driver.
  err = cudaSetDevice(device);
  int* d_probe = nullptr;
  int h_probe = 0;
  if (err == cudaSuccess) err = cudaMalloc(&d_probe, sizeof(int));
  if (err == cudaSuccess) {
    probeKernel<<<1, 1>>>(d_probe);
    err = cudaGetLastError();
    if (err == cudaSuccess) {
      err = cudaMemcpy(&h_probe, d_probe, sizeof(int), cudaMemcpyDeviceToHost);
    }
    cudaFree(d_probe);
  }
  if (err == cudaSuccess && h_probe != 42) err = cudaErrorUnknown;
  if (err != cudaSuccess) {
    if (why) *why = std::string(cudaGetErrorName(err)) + ": " + cudaGetErrorString(err);
    cudaGetLastError();
    return false;
  }
  if (why) why->clear();
  return true;
}

CudaKnn::CudaKnn(const CudaKnnOptions& options) : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  im.opt = options;
  std::string why;
  if (!deviceAvailable(&why, options.device)) {
    const std::string name = why.substr(0, why.find(':'));
    throw CudaError(name, "CudaKnn: no usable CUDA device: " + why);
  }
  GF_CUDA_CHECK(cudaSetDevice(options.device));
  cudaDeviceProp prop;
  GF_CUDA_CHECK(cudaGetDeviceProperties(&prop, options.device));
  im.device_name = prop.name;
  GF_CUDA_CHECK(cudaStreamCreateWithFlags(&im.stream, cudaStreamNonBlocking));
  GF_CUDA_CHECK(cudaStreamCreateWithFlags(&im.copy, cudaStreamNonBlocking));
  for (int c = 0; c < Impl::kMaxChunks; ++c) {
    GF_CUDA_CHECK(cudaEventCreateWithFlags(&im.kernel_done[c], cudaEventDisableTiming));
    GF_CUDA_CHECK(cudaEventCreateWithFlags(&im.copy_done[c], cudaEventDisableTiming));
  }
  GF_CUDA_CHECK(cudaEventCreateWithFlags(&im.order_done, cudaEventDisableTiming));
}

CudaKnn::~CudaKnn() {
  if (!impl_) return;
  Impl& im = *impl_;
  if (im.stream) cudaStreamSynchronize(im.stream);
  if (im.copy) cudaStreamSynchronize(im.copy);
  for (int c = 0; c < Impl::kMaxChunks; ++c) {
    if (im.kernel_done[c]) cudaEventDestroy(im.kernel_done[c]);
    if (im.copy_done[c]) cudaEventDestroy(im.copy_done[c]);
  }
  if (im.order_done) cudaEventDestroy(im.order_done);
  if (im.stream) cudaStreamDestroy(im.stream);
  if (im.copy) cudaStreamDestroy(im.copy);
}

const CudaKnnTimings& CudaKnn::lastTimings() const { return impl_->timings; }
std::string CudaKnn::deviceName() const { return impl_->device_name; }
std::size_t CudaKnn::deviceBytes() const { return impl_->device_bytes; }
const CudaKnnOptions& CudaKnn::options() const { return impl_->opt; }

void CudaKnn::search(const float* xyz, std::size_t n_in, int k, std::int32_t* indices,
                     float* sq_dists) {
  Impl& im = *impl_;
  im.timings = CudaKnnTimings();
  im.list_n = 0;
  const auto t_start = std::chrono::steady_clock::now();
  if (k < 1 || k > kMaxK) {
    throw std::invalid_argument("CudaKnn::search: k = " + std::to_string(k) +
                                " is out of range [1, " + std::to_string(kMaxK) + "]");
  }
  if (n_in >= (1u << 31) - 1) {
    throw std::invalid_argument("CudaKnn::search: " + std::to_string(n_in) +
                                " points exceed the 2^31 - 1 that int32 indices address");
  }
  if (n_in == 0) return;
  if (!xyz) throw std::invalid_argument("CudaKnn::search: null xyz");
  const int n = static_cast<int>(n_in);
  const bool download = indices != nullptr;
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  cudaStream_t st = im.stream;

  // ---- buffers for everything but the level tables
  const std::size_t rows = n_in * static_cast<std::size_t>(k);
  std::size_t sort_temp_bytes = 0;
  {
    cub::DoubleBuffer<unsigned long long> kb(nullptr, nullptr);
    cub::DoubleBuffer<unsigned int> vb(nullptr, nullptr);
    GF_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, sort_temp_bytes, kb, vb, n, 0,
                                                  3 * kCoordBits, st));
  }
  im.grow(im.xyz, n_in * 3 * sizeof(float), "the point copy");
  im.grow(im.keys_a, n_in * sizeof(unsigned long long), "the Morton keys");
  im.grow(im.keys_b, n_in * sizeof(unsigned long long), "the Morton keys");
  im.grow(im.vals_a, n_in * sizeof(unsigned int), "the sort order");
  im.grow(im.vals_b, n_in * sizeof(unsigned int), "the sort order");
  im.grow(im.start_level, n_in, "the cell starts");
  im.grow(im.sorted, n_in * sizeof(float4), "the sorted points");
  im.grow(im.sort_temp, sort_temp_bytes, "the sort scratch");
  const std::size_t small_bytes =
      64 + 32 * sizeof(unsigned int) + kStatCount * sizeof(unsigned long long);
  im.grow(im.small, small_bytes, "the bounds");
  im.grow(im.out_idx, rows * sizeof(std::int32_t), "the neighbour indices");
  if (sq_dists) im.grow(im.out_d2, rows * sizeof(float), "the neighbour distances");
  im.h_small.ensure(small_bytes);

  char* d_small = im.small.as<char>();
  int* d_bounds = reinterpret_cast<int*>(d_small);          // 7 ints
  float* d_frame = reinterpret_cast<float*>(d_small + 32);  // 5 floats
  unsigned int* d_hist = reinterpret_cast<unsigned int*>(d_small + 64);
  unsigned long long* d_stats =
      reinterpret_cast<unsigned long long*>(d_small + 64 + 32 * sizeof(unsigned int));

  // ---- upload
  auto t0 = std::chrono::steady_clock::now();
  const std::size_t in_bytes = n_in * 3 * sizeof(float);
  im.h_xyz.ensure(in_bytes);
  parallelCopy(im.h_xyz.ptr, xyz, in_bytes);
  GF_CUDA_CHECK(cudaMemcpyAsync(im.xyz.ptr, im.h_xyz.ptr, in_bytes, cudaMemcpyHostToDevice, st));
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  im.timings.upload_ms = msSince(t0);

  // ---- bounds, keys, sort, cell-start levels
  t0 = std::chrono::steady_clock::now();
  const float* d_xyz = im.xyz.as<float>();
  initBoundsKernel<<<1, 32, 0, st>>>(d_bounds);
  GF_CUDA_CHECK_LAUNCH();
  boundsKernel<<<std::min(blocksFor(n_in, 256), 1024u), 256, 0, st>>>(d_xyz, n, d_bounds);
  GF_CUDA_CHECK_LAUNCH();
  frameKernel<<<1, 1, 0, st>>>(d_bounds, d_frame);
  GF_CUDA_CHECK_LAUNCH();
  mortonKernel<<<blocksFor(n_in, 256), 256, 0, st>>>(
      d_xyz, n, d_frame, im.keys_a.as<unsigned long long>(), im.vals_a.as<unsigned int>());
  GF_CUDA_CHECK_LAUNCH();
  cub::DoubleBuffer<unsigned long long> kb(im.keys_a.as<unsigned long long>(),
                                           im.keys_b.as<unsigned long long>());
  cub::DoubleBuffer<unsigned int> vb(im.vals_a.as<unsigned int>(), im.vals_b.as<unsigned int>());
  std::size_t temp_bytes = im.sort_temp.bytes;
  GF_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(im.sort_temp.ptr, temp_bytes, kb, vb, n, 0,
                                                3 * kCoordBits, st));
  const unsigned long long* d_keys = kb.Current();
  const unsigned int* d_order = vb.Current();
  GF_CUDA_CHECK(cudaMemsetAsync(
      d_hist, 0, 32 * sizeof(unsigned int) + kStatCount * sizeof(unsigned long long), st));
  cellStartLevelKernel<<<blocksFor(n_in, 256), 256, 0, st>>>(
      d_keys, n, im.start_level.as<unsigned char>(), d_hist);
  GF_CUDA_CHECK_LAUNCH();
  gatherKernel<<<blocksFor(n_in, 256), 256, 0, st>>>(d_xyz, d_order, n, im.sorted.as<float4>());
  GF_CUDA_CHECK_LAUNCH();
  if (download) {  // the row order (sorted -> original) for the host-side scatter
    im.h_order.ensure(n_in * sizeof(unsigned int));
    GF_CUDA_CHECK(cudaEventRecord(im.order_done, st));
    GF_CUDA_CHECK(cudaStreamWaitEvent(im.copy, im.order_done, 0));
    GF_CUDA_CHECK(cudaMemcpyAsync(im.h_order.ptr, d_order, n_in * sizeof(unsigned int),
                                  cudaMemcpyDeviceToHost, im.copy));
  }
  GF_CUDA_CHECK(
      cudaMemcpyAsync(im.h_small.ptr, im.small.ptr, small_bytes, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaStreamSynchronize(st));

  const int* h_bounds = im.h_small.as<int>();
  const float* h_frame = reinterpret_cast<const float*>(im.h_small.as<char>() + 32);
  const unsigned int* h_hist = reinterpret_cast<const unsigned int*>(im.h_small.as<char>() + 64);
  if (h_bounds[6] > 0) {
    GF_CUDA_CHECK(cudaStreamSynchronize(im.copy));
    throw std::invalid_argument("CudaKnn::search: " + std::to_string(h_bounds[6]) + " of " +
                                std::to_string(n) +
                                " points have NaN/Inf coordinates; remove them first");
  }

  // ---- level choice: cells per level m_b = points starting a cell at level <= b
  std::size_t cells[kMaxLevels];
  std::size_t acc = 0;
  for (int b = 0; b < kMaxLevels; ++b) {
    acc += h_hist[b];
    cells[b] = acc;
  }
  // Finest level: where cells average <= ~1.7 points (finer levels would be nearly empty).
  int finest = kCoordBits;
  for (int b = 0; b < kMaxLevels; ++b) {
    if (cells[b] * 10 >= n_in * 6) {
      finest = b;
      break;
    }
  }
  GridDesc g;
  std::memset(&g, 0, sizeof g);
  g.ox = h_frame[0];
  g.oy = h_frame[1];
  g.oz = h_frame[2];
  g.inv = h_frame[4];
  const float edge = h_frame[3];
  // Rounding slack: a few float ulps of the largest coordinate magnitude involved.
  const float mag = std::max({std::fabs(g.ox), std::fabs(g.oy), std::fabs(g.oz)}) + edge;
  g.eps = 8.f * std::numeric_limits<float>::epsilon() * mag;
  const int min_pts_auto = std::max(1, std::min(k, n) / 4);
  g.min_points = im.opt.level_min_points > 0 ? im.opt.level_min_points : min_pts_auto;

  // Tables for levels finest..0; under a memory limit, drop the finest levels first.
  auto log2Cap = [&](int b) {
    unsigned int l2 = 5;
    while ((std::size_t(1) << l2) < 2 * cells[b]) ++l2;
    return l2;
  };
  auto tableSlots = [&](int fin) {
    std::size_t s = 0;
    for (int b = fin; b >= 0; --b) s += std::size_t(1) << log2Cap(b);
    return s;
  };
  const std::size_t slot_bytes = sizeof(unsigned long long) + sizeof(uint2);
  const std::size_t allow = im.allowance() + im.table_keys.bytes + im.table_vals.bytes;
  while (finest > 0 && tableSlots(finest) * slot_bytes * 9 / 8 > allow) --finest;
  g.nlev = finest + 1;
  std::size_t off = 0;
  for (int l = 0; l < g.nlev; ++l) {
    const int b = finest - l;
    LevelDesc& lv = g.lv[l];
    lv.bits = b;
    lv.cell = edge / static_cast<float>(1u << b);
    lv.log2cap = log2Cap(b);
    lv.table_off = off;
    off += std::size_t(1) << lv.log2cap;
  }
  im.grow(im.table_keys, off * sizeof(unsigned long long), "the grid cell tables");
  im.grow(im.table_vals, off * sizeof(uint2), "the grid cell tables");
  unsigned long long* d_tkeys = im.table_keys.as<unsigned long long>();
  uint2* d_tvals = im.table_vals.as<uint2>();
  GF_CUDA_CHECK(cudaMemsetAsync(d_tkeys, 0xff, off * sizeof(unsigned long long), st));
  insertCellsKernel<<<blocksFor(n_in, 256), 256, 0, st>>>(
      g, d_keys, im.start_level.as<unsigned char>(), n, d_tkeys, d_tvals);
  GF_CUDA_CHECK_LAUNCH();
  closeCellsKernel<<<blocksFor(n_in, 256), 256, 0, st>>>(
      g, d_keys, im.start_level.as<unsigned char>(), n, d_tkeys, d_tvals);
  GF_CUDA_CHECK_LAUNCH();
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  im.timings.grid_ms = msSince(t0);
  im.timings.levels = g.nlev;
  im.timings.finest_bits = finest;

  // ---- queries in chunks of Morton-ordered rows; each chunk's rows download while the next
  //      chunk computes, and the host scatters them to their original rows meanwhile.
  t0 = std::chrono::steady_clock::now();
  const int auto_chunks = std::max(1, std::min(Impl::kMaxChunks, (n + 32767) / 32768));
  const int chunks =
      !download ? 1
                : (im.opt.download_chunks > 0 ? std::min(im.opt.download_chunks, Impl::kMaxChunks)
                                              : auto_chunks);
  const int per_chunk = (n + chunks - 1) / chunks;
  std::int32_t* d_idx = im.out_idx.as<std::int32_t>();
  float* d_d2 = sq_dists ? im.out_d2.as<float>() : nullptr;
  unsigned long long* stats = im.opt.collect_stats ? d_stats : nullptr;
  if (download) {
    im.h_idx.ensure(rows * sizeof(std::int32_t));
    if (sq_dists) im.h_d2.ensure(rows * sizeof(float));
  }
  for (int c = 0; c < chunks; ++c) {
    const int b = c * per_chunk, e = std::min(n, b + per_chunk);
    if (b >= e) break;
    const unsigned int blocks = blocksFor(static_cast<std::size_t>(e - b) * kWarp, kQueryBlock);
    const float4* d_pts = im.sorted.as<float4>();
    // Variants: k > 32 (two list halves), cells nearest first.
    const bool two = k > 32;
#define GF_KNN_LAUNCH(TWO, SORT) \
  knnKernel<TWO, SORT>           \
      <<<blocks, kQueryBlock, 0, st>>>(g, d_pts, d_tkeys, d_tvals, n, b, e, k, d_idx, d_d2, stats)
    if (im.opt.sort_cells) {
      if (two)
        GF_KNN_LAUNCH(true, true);
      else
        GF_KNN_LAUNCH(false, true);
    } else {
      if (two)
        GF_KNN_LAUNCH(true, false);
      else
        GF_KNN_LAUNCH(false, false);
    }
#undef GF_KNN_LAUNCH
    GF_CUDA_CHECK_LAUNCH();
    if (download) {
      const std::size_t r0 = static_cast<std::size_t>(b) * k,
                        nr = static_cast<std::size_t>(e - b) * k;
      GF_CUDA_CHECK(cudaEventRecord(im.kernel_done[c], st));
      GF_CUDA_CHECK(cudaStreamWaitEvent(im.copy, im.kernel_done[c], 0));
      GF_CUDA_CHECK(cudaMemcpyAsync(im.h_idx.as<std::int32_t>() + r0, d_idx + r0,
                                    nr * sizeof(std::int32_t), cudaMemcpyDeviceToHost, im.copy));
      if (sq_dists) {
        GF_CUDA_CHECK(cudaMemcpyAsync(im.h_d2.as<float>() + r0, d_d2 + r0, nr * sizeof(float),
                                      cudaMemcpyDeviceToHost, im.copy));
      }
      GF_CUDA_CHECK(cudaEventRecord(im.copy_done[c], im.copy));
    }
  }
  if (download) {
    const unsigned int* order = im.h_order.as<unsigned int>();
    const std::int32_t* h_idx = im.h_idx.as<std::int32_t>();
    const float* h_d2 = sq_dists ? im.h_d2.as<float>() : nullptr;
    const std::size_t row_i = static_cast<std::size_t>(k) * sizeof(std::int32_t);
    const std::size_t row_f = static_cast<std::size_t>(k) * sizeof(float);
    for (int c = 0; c < chunks; ++c) {
      const int b = c * per_chunk, e = std::min(n, b + per_chunk);
      if (b >= e) break;
      GF_CUDA_CHECK(cudaEventSynchronize(im.copy_done[c]));
#pragma omp parallel for schedule(static) if (e - b > 4096)
      for (int s = b; s < e; ++s) {
        const std::size_t dst = static_cast<std::size_t>(order[s]) * k;
        std::memcpy(indices + dst, h_idx + static_cast<std::size_t>(s) * k, row_i);
        if (h_d2) std::memcpy(sq_dists + dst, h_d2 + static_cast<std::size_t>(s) * k, row_f);
      }
    }
  }
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  GF_CUDA_CHECK(cudaStreamSynchronize(im.copy));
  im.timings.query_ms = msSince(t0);  // with the overlapped download and scatter
  im.list_n = n_in;
  im.list_k = k;
  if (stats) {
    unsigned long long h[kStatCount];
    GF_CUDA_CHECK(cudaMemcpy(h, d_stats, sizeof h, cudaMemcpyDeviceToHost));
    im.timings.candidates_per_query = static_cast<double>(h[kStatCandidates]) / n;
    im.timings.insertions_per_query = static_cast<double>(h[kStatInsertions]) / n;
    im.timings.shells_per_query = static_cast<double>(h[kStatShells]) / n;
    im.timings.levels_per_query = static_cast<double>(h[kStatLevels]) / n;
    im.timings.mean_query_cycles = static_cast<double>(h[kStatCycles]) / n;
    im.timings.max_query_cycles = static_cast<double>(h[kStatMaxCycles]);
    auto asFloat = [](unsigned long long v) {
      const unsigned int b = static_cast<unsigned int>(v);
      float f;
      std::memcpy(&f, &b, sizeof f);
      return f;
    };
    std::ostringstream os;
    os << h[kStatOver100k] << " queries > 1e5 cycles, " << h[kStatOver1M]
       << " > 1e6; slowest: " << h[kStatSlowCand] << " candidates, " << h[kStatSlowIns]
       << " insertions, " << h[kStatSlowShells] << " shells, " << h[kStatSlowLevels]
       << " levels, last level 2^" << h[kStatSlowBits] << " cells/axis (cell "
       << edge / static_cast<float>(1u << h[kStatSlowBits]) << " m), bound "
       << std::sqrt(asFloat(h[kStatSlowLim])) << " m, K-th distance "
       << std::sqrt(asFloat(h[kStatSlowKd])) << " m";
    im.timings.detail = os.str();
  }
  im.timings.total_ms = msSince(t_start);
}

void CudaKnn::neighborhoodPca(float* normals, float* eigenvalues, std::uint8_t* valid) {
  Impl& im = *impl_;
  im.requireLists("neighborhoodPca");
  const auto t0 = std::chrono::steady_clock::now();
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  const std::size_t n = im.list_n;
  const std::size_t bytes = n * (6 * sizeof(float) + 1);
  im.grow(im.pca, bytes, "the PCA results");
  im.h_pca.ensure(bytes);
  float* d_normals = im.pca.as<float>();
  float* d_eigen = d_normals + 3 * n;
  std::uint8_t* d_valid = reinterpret_cast<std::uint8_t*>(d_eigen + 3 * n);
  pcaKernel<<<blocksFor(n, 128), 128, 0, im.stream>>>(
      im.xyz.as<float>(), im.sorted.as<float4>(), im.out_idx.as<std::int32_t>(),
      static_cast<int>(n), im.list_k, d_normals, d_eigen, d_valid);
  GF_CUDA_CHECK_LAUNCH();
  GF_CUDA_CHECK(
      cudaMemcpyAsync(im.h_pca.ptr, im.pca.ptr, bytes, cudaMemcpyDeviceToHost, im.stream));
  GF_CUDA_CHECK(cudaStreamSynchronize(im.stream));
  const float* h = im.h_pca.as<float>();
  parallelCopy(normals, h, 3 * n * sizeof(float));
  parallelCopy(eigenvalues, h + 3 * n, 3 * n * sizeof(float));
  std::memcpy(valid, h + 6 * n, n);
  im.timings.pca_ms = msSince(t0);
}

void CudaKnn::countFlaggedNeighbors(const std::uint8_t* flags, std::uint16_t* flagged,
                                    std::uint16_t* neighbors) {
  Impl& im = *impl_;
  im.requireLists("countFlaggedNeighbors");
  const auto t0 = std::chrono::steady_clock::now();
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  const std::size_t n = im.list_n;
  im.grow(im.flags, n, "the point flags");
  im.grow(im.counts, 2 * n * sizeof(std::uint16_t), "the neighbour counts");
  im.h_flags.ensure(n);
  im.h_counts.ensure(2 * n * sizeof(std::uint16_t));
  parallelCopy(im.h_flags.ptr, flags, n);
  GF_CUDA_CHECK(
      cudaMemcpyAsync(im.flags.ptr, im.h_flags.ptr, n, cudaMemcpyHostToDevice, im.stream));
  std::uint16_t* d_counts = im.counts.as<std::uint16_t>();
  countKernel<<<blocksFor(n, 256), 256, 0, im.stream>>>(
      im.sorted.as<float4>(), im.out_idx.as<std::int32_t>(), static_cast<int>(n), im.list_k,
      im.flags.as<std::uint8_t>(), d_counts, d_counts + n);
  GF_CUDA_CHECK_LAUNCH();
  GF_CUDA_CHECK(cudaMemcpyAsync(im.h_counts.ptr, d_counts, 2 * n * sizeof(std::uint16_t),
                                cudaMemcpyDeviceToHost, im.stream));
  GF_CUDA_CHECK(cudaStreamSynchronize(im.stream));
  parallelCopy(flagged, im.h_counts.ptr, n * sizeof(std::uint16_t));
  parallelCopy(neighbors, im.h_counts.as<std::uint16_t>() + n, n * sizeof(std::uint16_t));
  im.timings.count_ms = msSince(t0);
}

std::size_t CudaKnn::listPoints() const { return impl_->list_n; }

}  // namespace ground_filter
