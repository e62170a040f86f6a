// Private: the multi-level hashed grid of the KNN search (constants, cell tables, device helpers
// shared with the query kernel) and the launchers of its construction kernels.
#ifndef GROUND_FILTER_CUDA_SRC_KNN_GRID_CUH
#define GROUND_FILTER_CUDA_SRC_KNN_GRID_CUH

#include <cuda_runtime.h>

#include <cstdint>
#include <cstring>

namespace ground_filter {
namespace cuda_impl {

constexpr int kCoordBits = 21;  // per axis; 3 * 21 = 63-bit Morton keys
constexpr std::uint32_t kCoordMax = (1u << kCoordBits) - 1;
constexpr int kMaxLevels = kCoordBits + 1;  // level b has 2^b cells per axis, b = 0..21
/// The Morton sort orders the keys' top 3 * kSortedLevels bits only (6 radix passes instead of 8):
/// the cells of levels 0..16 (1/65536 of the cube's edge) are runs of the sorted points, and no
/// finer level is used (a finer one would only order points a few mm apart on a KITTI frame).
constexpr int kSortedLevels = 16;
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

/// initBounds + bounds + frame: `bounds` [0..2] min xyz, [3..5] max xyz (ordered ints), [6]
/// non-finite point count; `frame` [0..2] origin, [3] cube edge, [4] 2^21 / edge.
void launchBoundsAndFrame(const float* xyz, int n, int* bounds, float* frame, cudaStream_t st);
/// 63-bit Morton key of every point and the identity order.
void launchMorton(const float* xyz, int n, const float* frame, unsigned long long* keys,
                  unsigned int* vals, cudaStream_t st);
/// Per sorted point: coarsest level at which it starts a new cell, and their histogram.
void launchCellStartLevel(const unsigned long long* keys, int n, unsigned char* start_level,
                          unsigned int* hist, cudaStream_t st);
/// Sorted points (x, y, z, original index as int bits).
void launchGather(const float* xyz, const unsigned int* order, int n, float4* sorted,
                  cudaStream_t st);
/// heads[i] = sorted point i starts a run of identical points (0/1).
void launchRunHeads(const float4* sorted, int n, unsigned int* heads, cudaStream_t st);
/// With run_id = inclusive scan of the heads: run_end[run_id[i] - 1] = end of i's run (scratch),
/// then run_stop[i] = end of i's run, per sorted point.
void launchRunEnds(const float4* sorted, const unsigned int* run_id, int n, unsigned int* run_end,
                   unsigned int* run_stop, cudaStream_t st);
/// Fills the cell tables of every level of `g` (tables preset to kEmptyKey).
void launchBuildCells(const GridDesc& g, const unsigned long long* keys,
                      const unsigned char* start_level, int n, unsigned long long* table_keys,
                      uint2* table_vals, cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_KNN_GRID_CUH
