// Exact K-nearest-neighbour search on the GPU over a hashed multi-level uniform grid.
//
// Pipeline of one search() (one stream, two host synchronisations):
//   upload -> bounds -> Morton keys (21 bits per axis over the bounding cube) -> radix sort ->
//   per-point "first level at which this point starts a new cell" + histogram -> [sync: level
//   choice on the host] -> one hash table per level (cell key -> first point, count) ->
//   one warp per query point -> [sync] download.
// Sorting along the Morton curve makes every cell of every power-of-two level a contiguous range
// of the sorted points, so a single sort serves all levels.

#include "ground_filter/cuda_knn.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cub/device/device_radix_sort.cuh>
#include <limits>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace ground_filter {

namespace {

/// Throws CudaError naming the failed call and the CUDA error.
void checkCuda(cudaError_t err, const char* call, const char* file, int line) {
  if (err == cudaSuccess) return;
  std::ostringstream os;
  os << "CUDA error " << cudaGetErrorName(err) << " (" << cudaGetErrorString(err) << ") in "
     << call << " at " << file << ":" << line;
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
constexpr int kStarveShells = 2;  // shells searched before a starving query moves a level up

/// One grid level: a hash table from Morton cell key to (first sorted point, point count).
struct LevelDesc {
  int bits;                       // 2^bits cells per axis
  float cell;                     // cell edge [m]
  unsigned int log2cap;           // table capacity = 2^log2cap slots
  unsigned long long table_off;   // first slot of this level in the shared slot arrays
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
  if (threadIdx.x < 3) b[threadIdx.x] = 0x7fffffff;
  else if (threadIdx.x < 6) b[threadIdx.x] = static_cast<int>(0x80000000u);
  else if (threadIdx.x == 6) b[6] = 0;
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
    if (!(lo[a] <= hi)) lo[a] = 0.f;  // no finite point at all
    else ext = fmaxf(ext, hi - lo[a]);
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
  sorted[i] = make_float4(xyz[3 * j], xyz[3 * j + 1], xyz[3 * j + 2],
                          __int_as_float(static_cast<int>(j)));
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
    table_vals[lv.table_off + h].y = static_cast<unsigned int>(i + 1) - table_vals[lv.table_off + h].x;
  }
}

// ------------------------------------------------------------------ the query kernel

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

/// One warp per query (queries in Morton order for locality). kTwoHalves: k > 32.
template <bool kTwoHalves>
__global__ void __launch_bounds__(kQueryBlock) knnKernel(
    const __grid_constant__ GridDesc g, const float4* __restrict__ pts,
    const unsigned long long* __restrict__ tkeys, const uint2* __restrict__ tvals, int n, int k,
    std::int32_t* __restrict__ out_idx, float* __restrict__ out_d2) {
  const unsigned full = 0xffffffffu;
  const int lane = threadIdx.x & 31;
  const long long qi = (static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x) >> 5;
  if (qi >= n) return;  // uniform per warp
  const float4 q = pts[qi];
  const std::uint32_t qx = quantize(q.x, g.ox, g.inv), qy = quantize(q.y, g.oy, g.inv),
                      qz = quantize(q.z, g.oz, g.inv);

  // Level: the finest whose own cell holds >= min_points points (lanes test one level each).
  bool ok = false;
  if (lane < g.nlev) {
    const LevelDesc& lv = g.lv[lane];
    const int s = kCoordBits - lv.bits;
    const uint2 c = lookupCell(tkeys, tvals, lv, morton(qx >> s, qy >> s, qz >> s));
    ok = static_cast<int>(c.y) >= g.min_points;
  }
  const unsigned okm = __ballot_sync(full, ok);
  int li = okm ? __ffs(okm) - 1 : g.nlev - 1;

  WarpList w;
  for (;;) {  // one pass per level tried; a pass that starves moves to the next coarser level
    const LevelDesc& lv = g.lv[li];
    const int shift = kCoordBits - lv.bits;
    const int cx = static_cast<int>(qx >> shift), cy = static_cast<int>(qy >> shift),
              cz = static_cast<int>(qz >> shift);
    const int last = (1 << lv.bits) - 1;
    const float cs = lv.cell, eps = g.eps;
    // Cell index of coordinate v clamped to [-2, last + 2] (no int overflow for huge radii).
    auto cellOf = [&](float v, float o) {
      return static_cast<int>(fminf(fmaxf(floorf((v - o) / cs), -2.f), static_cast<float>(last + 2)));
    };
    w.dlo = w.dhi = w.kd = INFINITY;
    w.ilo = w.ihi = w.ki = kEmptyIndex;
    bool restart = false;

    for (int r = 0;; ++r) {
      int x0 = max(cx - r, 0), x1 = min(cx + r, last);
      int y0 = max(cy - r, 0), y1 = min(cy + r, last);
      int z0 = max(cz - r, 0), z1 = min(cz + r, last);
      if (w.ki != kEmptyIndex) {  // only cells that can hold a point within the K-th distance
        const float rad = sqrtf(w.kd) + eps;
        x0 = max(x0, cellOf(q.x - rad, g.ox) - 1);
        x1 = min(x1, cellOf(q.x + rad, g.ox) + 1);
        y0 = max(y0, cellOf(q.y - rad, g.oy) - 1);
        y1 = min(y1, cellOf(q.y + rad, g.oy) + 1);
        z0 = max(z0, cellOf(q.z - rad, g.oz) - 1);
        z1 = min(z1, cellOf(q.z + rad, g.oz) + 1);
      }
      const int nx = x1 - x0 + 1, ny = y1 - y0 + 1, nz = z1 - z0 + 1;
      const int total = (nx > 0 && ny > 0 && nz > 0) ? nx * ny * nz : 0;
      for (int base = 0; base < total; base += kWarp) {
        // Each lane looks up one cell of the shell.
        uint2 cell = make_uint2(0u, 0u);
        const int t = base + lane;
        if (t < total) {
          const int ix = x0 + t % nx, iy = y0 + (t / nx) % ny, iz = z0 + t / (nx * ny);
          const int cheb = max(max(abs(ix - cx), abs(iy - cy)), abs(iz - cz));
          bool visit = cheb == r;
          if (visit && w.ki != kEmptyIndex) {
            const float lx = g.ox + ix * cs, ly = g.oy + iy * cs, lz = g.oz + iz * cs;
            const float ex = fmaxf(fmaxf(lx - q.x, q.x - (lx + cs)) - eps, 0.f);
            const float ey = fmaxf(fmaxf(ly - q.y, q.y - (ly + cs)) - eps, 0.f);
            const float ez = fmaxf(fmaxf(lz - q.z, q.z - (lz + cs)) - eps, 0.f);
            visit = ex * ex + ey * ey + ez * ez <= w.kd;
          }
          if (visit) {
            cell = lookupCell(tkeys, tvals, lv,
                              morton(static_cast<std::uint32_t>(ix), static_cast<std::uint32_t>(iy),
                                     static_cast<std::uint32_t>(iz)));
          }
        }
        // Concatenate the cells' point ranges across the warp.
        unsigned int incl = cell.y;
        for (int o = 1; o < kWarp; o <<= 1) {
          const unsigned int v = __shfl_up_sync(full, incl, o);
          if (lane >= o) incl += v;
        }
        const unsigned int excl = incl - cell.y;
        const unsigned int count = __shfl_sync(full, incl, 31);
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
          unsigned m = __ballot_sync(full, valid && pairLess(d, id, w.kd, w.ki));
          while (m) {
            const int src = __ffs(m) - 1;
            const float dd = __shfl_sync(full, d, src);
            const int ii = __shfl_sync(full, id, src);
            warpInsert<kTwoHalves>(w, dd, ii, lane, k);
            m &= ~(1u << src);
            m &= __ballot_sync(full, valid && pairLess(d, id, w.kd, w.ki));
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
      // Still short of k points two shells out: this level is too fine around q (an isolated
      // point); start again one level coarser rather than walking many empty shells.
      if (w.ki == kEmptyIndex && r >= kStarveShells && li + 1 < g.nlev) {
        restart = true;
        break;
      }
    }
    if (!restart) break;
    ++li;
  }

  const std::size_t row = static_cast<std::size_t>(__float_as_int(q.w)) * k;
  if (lane < k) {
    out_idx[row + lane] = w.ilo == kEmptyIndex ? -1 : w.ilo;
    if (out_d2) out_d2[row + lane] = w.ilo == kEmptyIndex ? INFINITY : w.dlo;
  }
  if (kTwoHalves && lane + 32 < k) {
    out_idx[row + lane + 32] = w.ihi == kEmptyIndex ? -1 : w.ihi;
    if (out_d2) out_d2[row + lane + 32] = w.ihi == kEmptyIndex ? INFINITY : w.dhi;
  }
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
};

/// memcpy split over a few threads (a single core copies far slower than PCIe delivers).
void parallelCopy(void* dst, const void* src, std::size_t bytes) {
  const std::size_t kMinPerThread = 4u << 20;
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  const unsigned threads =
      static_cast<unsigned>(std::min<std::size_t>(std::min(hw, 16u), bytes / kMinPerThread + 1));
  if (threads <= 1) {
    std::memcpy(dst, src, bytes);
    return;
  }
  std::vector<std::thread> pool;
  const std::size_t chunk = (bytes + threads - 1) / threads;
  for (unsigned t = 0; t < threads; ++t) {
    const std::size_t b = t * chunk;
    if (b >= bytes) break;
    const std::size_t len = std::min(chunk, bytes - b);
    pool.emplace_back([=] {
      std::memcpy(static_cast<char*>(dst) + b, static_cast<const char*>(src) + b, len);
    });
  }
  for (auto& th : pool) th.join();
}

}  // namespace

// ------------------------------------------------------------------ CudaKnn

struct CudaKnn::Impl {
  CudaKnnOptions opt;
  cudaStream_t stream = nullptr;
  std::string device_name;
  std::size_t device_bytes = 0;
  CudaKnnTimings timings;

  DeviceBuffer xyz, keys_a, keys_b, vals_a, vals_b, start_level, sorted, sort_temp, small,
      table_keys, table_vals, out_idx, out_d2;
  PinnedBuffer h_small, h_xyz, h_idx, h_d2;

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
    if (err == cudaSuccess) err = cudaMemcpy(&h_probe, d_probe, sizeof(int), cudaMemcpyDeviceToHost);
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
}

CudaKnn::~CudaKnn() {
  if (impl_ && impl_->stream) {
    cudaStreamSynchronize(impl_->stream);
    cudaStreamDestroy(impl_->stream);
  }
}

const CudaKnnTimings& CudaKnn::lastTimings() const { return impl_->timings; }
std::string CudaKnn::deviceName() const { return impl_->device_name; }
std::size_t CudaKnn::deviceBytes() const { return impl_->device_bytes; }
const CudaKnnOptions& CudaKnn::options() const { return impl_->opt; }

void CudaKnn::search(const float* xyz, std::size_t n_in, int k, std::int32_t* indices,
                     float* sq_dists) {
  Impl& im = *impl_;
  im.timings = CudaKnnTimings();
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
  if (!xyz || !indices) throw std::invalid_argument("CudaKnn::search: null xyz or indices");
  const int n = static_cast<int>(n_in);
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
  const std::size_t small_bytes = 64 + 32 * sizeof(unsigned int);  // bounds, frame, histogram
  im.grow(im.small, small_bytes, "the bounds");
  im.grow(im.out_idx, rows * sizeof(std::int32_t), "the neighbour indices");
  if (sq_dists) im.grow(im.out_d2, rows * sizeof(float), "the neighbour distances");
  im.h_small.ensure(small_bytes);

  int* d_bounds = im.small.as<int>();                               // 7 ints
  float* d_frame = reinterpret_cast<float*>(im.small.as<char>() + 32);  // 5 floats
  unsigned int* d_hist = reinterpret_cast<unsigned int*>(im.small.as<char>() + 64);

  // ---- upload
  auto t0 = std::chrono::steady_clock::now();
  const std::size_t in_bytes = n_in * 3 * sizeof(float);
  if (im.opt.pinned_staging) {
    im.h_xyz.ensure(in_bytes);
    parallelCopy(im.h_xyz.ptr, xyz, in_bytes);
    GF_CUDA_CHECK(cudaMemcpyAsync(im.xyz.ptr, im.h_xyz.ptr, in_bytes, cudaMemcpyHostToDevice, st));
  } else {
    GF_CUDA_CHECK(cudaMemcpyAsync(im.xyz.ptr, xyz, in_bytes, cudaMemcpyHostToDevice, st));
  }
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
  GF_CUDA_CHECK(cudaMemsetAsync(d_hist, 0, 32 * sizeof(unsigned int), st));
  cellStartLevelKernel<<<blocksFor(n_in, 256), 256, 0, st>>>(
      d_keys, n, im.start_level.as<unsigned char>(), d_hist);
  GF_CUDA_CHECK_LAUNCH();
  gatherKernel<<<blocksFor(n_in, 256), 256, 0, st>>>(d_xyz, d_order, n, im.sorted.as<float4>());
  GF_CUDA_CHECK_LAUNCH();
  GF_CUDA_CHECK(cudaMemcpyAsync(im.h_small.ptr, im.small.ptr, small_bytes, cudaMemcpyDeviceToHost,
                                st));
  GF_CUDA_CHECK(cudaStreamSynchronize(st));

  const int* h_bounds = static_cast<const int*>(im.h_small.ptr);
  const float* h_frame = reinterpret_cast<const float*>(static_cast<char*>(im.h_small.ptr) + 32);
  const unsigned int* h_hist =
      reinterpret_cast<const unsigned int*>(static_cast<char*>(im.h_small.ptr) + 64);
  if (h_bounds[6] > 0) {
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
  auto tableSlots = [&](int fin) {
    std::size_t s = 0;
    for (int b = fin; b >= 0; --b) {
      unsigned int l2 = 5;
      while ((std::size_t(1) << l2) < 2 * cells[b]) ++l2;
      s += std::size_t(1) << l2;
    }
    return s;
  };
  const std::size_t slot_bytes = sizeof(unsigned long long) + sizeof(uint2);
  std::size_t allow = im.allowance() + im.table_keys.bytes + im.table_vals.bytes;
  while (finest > 0 && tableSlots(finest) * slot_bytes * 9 / 8 > allow) --finest;
  g.nlev = finest + 1;
  std::size_t off = 0;
  for (int l = 0; l < g.nlev; ++l) {
    const int b = finest - l;
    LevelDesc& lv = g.lv[l];
    lv.bits = b;
    lv.cell = edge / static_cast<float>(1u << b);
    unsigned int l2 = 5;
    while ((std::size_t(1) << l2) < 2 * cells[b]) ++l2;
    lv.log2cap = l2;
    lv.table_off = off;
    off += std::size_t(1) << l2;
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

  // ---- queries
  t0 = std::chrono::steady_clock::now();
  const std::size_t threads = n_in * kWarp;
  const unsigned int blocks = blocksFor(threads, kQueryBlock);
  float* d_d2 = sq_dists ? im.out_d2.as<float>() : nullptr;
  if (k > 32) {
    knnKernel<true><<<blocks, kQueryBlock, 0, st>>>(g, im.sorted.as<float4>(), d_tkeys, d_tvals,
                                                     n, k, im.out_idx.as<std::int32_t>(), d_d2);
  } else {
    knnKernel<false><<<blocks, kQueryBlock, 0, st>>>(g, im.sorted.as<float4>(), d_tkeys, d_tvals,
                                                      n, k, im.out_idx.as<std::int32_t>(), d_d2);
  }
  GF_CUDA_CHECK_LAUNCH();
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  im.timings.query_ms = msSince(t0);

  // ---- download
  t0 = std::chrono::steady_clock::now();
  const std::size_t idx_bytes = rows * sizeof(std::int32_t), d2_bytes = rows * sizeof(float);
  if (im.opt.pinned_staging) {
    im.h_idx.ensure(idx_bytes);
    if (sq_dists) im.h_d2.ensure(d2_bytes);
    GF_CUDA_CHECK(cudaMemcpyAsync(im.h_idx.ptr, im.out_idx.ptr, idx_bytes, cudaMemcpyDeviceToHost,
                                  st));
    if (sq_dists) {
      GF_CUDA_CHECK(
          cudaMemcpyAsync(im.h_d2.ptr, im.out_d2.ptr, d2_bytes, cudaMemcpyDeviceToHost, st));
    }
    GF_CUDA_CHECK(cudaStreamSynchronize(st));
    parallelCopy(indices, im.h_idx.ptr, idx_bytes);
    if (sq_dists) parallelCopy(sq_dists, im.h_d2.ptr, d2_bytes);
  } else {
    GF_CUDA_CHECK(cudaMemcpyAsync(indices, im.out_idx.ptr, idx_bytes, cudaMemcpyDeviceToHost, st));
    if (sq_dists) {
      GF_CUDA_CHECK(cudaMemcpyAsync(sq_dists, im.out_d2.ptr, d2_bytes, cudaMemcpyDeviceToHost, st));
    }
    GF_CUDA_CHECK(cudaStreamSynchronize(st));
  }
  im.timings.download_ms = msSince(t0);
  im.timings.total_ms = msSince(t_start);
}

}  // namespace ground_filter
