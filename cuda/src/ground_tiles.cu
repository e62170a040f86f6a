// Plane tiles: keys, heads, voted lists (see ground_tiles.cuh).
#include <cmath>

#include "cuda_util.cuh"
#include "ground_tiles.cuh"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

namespace {

constexpr int kThreads = kGroundThreads;

using normal::cellIndex;

__global__ void tileKeysKernel(const float* __restrict__ xyz, int n, bool local_planes,
                               double min_x, double min_y, double inv_tile, int ybits,
                               unsigned long long* keys, unsigned int* vals) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  unsigned long long key = 0;
  if (local_planes) {
    const std::size_t s = 3 * static_cast<std::size_t>(i);
    const std::uint32_t tx = cellIndex(xyz[s], min_x, inv_tile);
    const std::uint32_t ty = cellIndex(xyz[s + 1], min_y, inv_tile);
    key = (static_cast<unsigned long long>(tx) << ybits) | ty;
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

}  // namespace

void launchTileKeys(const float* xyz, int n, bool local_planes, double min_x, double min_y,
                    double inv_tile, int ybits, unsigned long long* keys, unsigned int* vals,
                    cudaStream_t st) {
  tileKeysKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(xyz, n, local_planes, min_x, min_y,
                                                              inv_tile, ybits, keys, vals);
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

}  // namespace cuda_impl
}  // namespace ground_filter
