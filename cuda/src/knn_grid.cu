// Construction of the KNN grid: bounds, Morton keys, cell starts, hashed cell tables.
#include <algorithm>

#include "cuda_util.cuh"
#include "knn_grid.cuh"

namespace ground_filter {
namespace cuda_impl {

namespace {

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
/// Sorted point i starts a run of identical points (equal coordinates imply equal keys, and a
/// run's original indices ascend: the sort is stable).
__device__ inline bool runHead(const float4* __restrict__ sorted, int i) {
  if (i == 0) return true;
  const float4 a = sorted[i - 1], b = sorted[i];
  return !(a.x == b.x && a.y == b.y && a.z == b.z);
}

/// heads[i] = sorted point i starts a run of identical points.
__global__ void runHeadsKernel(const float4* __restrict__ sorted, int n, unsigned int* heads) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) heads[i] = runHead(sorted, i);
}

/// run_end[run_id[i] - 1] = i + 1 for the last point i of each run.
__global__ void runEndsKernel(const float4* __restrict__ sorted,
                              const unsigned int* __restrict__ run_id, int n,
                              unsigned int* run_end) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  if (i + 1 == n || runHead(sorted, i + 1)) run_end[run_id[i] - 1] = i + 1;
}

/// run_stop[i] = end of sorted point i's run.
__global__ void runStopKernel(const unsigned int* __restrict__ run_id,
                              const unsigned int* __restrict__ run_end, int n,
                              unsigned int* run_stop) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) run_stop[i] = run_end[run_id[i] - 1];
}

}  // namespace

void launchRunHeads(const float4* sorted, int n, unsigned int* heads, cudaStream_t st) {
  runHeadsKernel<<<blocksFor(n, 256), 256, 0, st>>>(sorted, n, heads);
  GF_CUDA_CHECK_LAUNCH();
}

void launchRunEnds(const float4* sorted, const unsigned int* run_id, int n, unsigned int* run_end,
                   unsigned int* run_stop, cudaStream_t st) {
  runEndsKernel<<<blocksFor(n, 256), 256, 0, st>>>(sorted, run_id, n, run_end);
  GF_CUDA_CHECK_LAUNCH();
  runStopKernel<<<blocksFor(n, 256), 256, 0, st>>>(run_id, run_end, n, run_stop);
  GF_CUDA_CHECK_LAUNCH();
}

void launchBoundsAndFrame(const float* xyz, int n, int* bounds, float* frame, cudaStream_t st) {
  initBoundsKernel<<<1, 32, 0, st>>>(bounds);
  GF_CUDA_CHECK_LAUNCH();
  boundsKernel<<<std::min(blocksFor(n, 256), 1024u), 256, 0, st>>>(xyz, n, bounds);
  GF_CUDA_CHECK_LAUNCH();
  frameKernel<<<1, 1, 0, st>>>(bounds, frame);
  GF_CUDA_CHECK_LAUNCH();
}

void launchMorton(const float* xyz, int n, const float* frame, unsigned long long* keys,
                  unsigned int* vals, cudaStream_t st) {
  mortonKernel<<<blocksFor(n, 256), 256, 0, st>>>(xyz, n, frame, keys, vals);
  GF_CUDA_CHECK_LAUNCH();
}

void launchCellStartLevel(const unsigned long long* keys, int n, unsigned char* start_level,
                          unsigned int* hist, cudaStream_t st) {
  cellStartLevelKernel<<<blocksFor(n, 256), 256, 0, st>>>(keys, n, start_level, hist);
  GF_CUDA_CHECK_LAUNCH();
}

void launchGather(const float* xyz, const unsigned int* order, int n, float4* sorted,
                  cudaStream_t st) {
  gatherKernel<<<blocksFor(n, 256), 256, 0, st>>>(xyz, order, n, sorted);
  GF_CUDA_CHECK_LAUNCH();
}

void launchBuildCells(const GridDesc& g, const unsigned long long* keys,
                      const unsigned char* start_level, int n, unsigned long long* table_keys,
                      uint2* table_vals, cudaStream_t st) {
  insertCellsKernel<<<blocksFor(n, 256), 256, 0, st>>>(g, keys, start_level, n, table_keys,
                                                       table_vals);
  GF_CUDA_CHECK_LAUNCH();
  closeCellsKernel<<<blocksFor(n, 256), 256, 0, st>>>(g, keys, start_level, n, table_keys,
                                                      table_vals);
  GF_CUDA_CHECK_LAUNCH();
}

}  // namespace cuda_impl
}  // namespace ground_filter
