// Private: the plane tiles on the device: tile keys, tile heads and the voted lists per tile.
#ifndef GROUND_FILTER_CUDA_SRC_GROUND_TILES_CUH
#define GROUND_FILTER_CUDA_SRC_GROUND_TILES_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "ground_common.cuh"

namespace ground_filter {
namespace cuda_impl {

/// Tile key (tx << ybits | ty, ty < 2^ybits: the order of the CPU's tx << 32 | ty in fewer bits)
/// of every point, 0 without local planes; vals = identity.
void launchTileKeys(const float* xyz, int n, bool local_planes, double min_x, double min_y,
                    double inv_tile, int ybits, unsigned long long* keys, unsigned int* vals,
                    cudaStream_t st);
/// heads[j] = sorted tile key j starts a tile (j < n); heads[n] = 0. vflags[j] =
/// voted[order[j]], gflags[i] = voted[i] (both with a 0 at n).
void launchTileFlags(const unsigned long long* sorted_keys, const unsigned int* order,
                     const std::uint8_t* voted, int n, unsigned int* heads, unsigned int* vflags,
                     unsigned int* gflags, cudaStream_t st);
/// From the scans: tile_begin[t] (and tile_begin[ntiles] = n), the voted points per tile in tile
/// order (vlist), all voted points ascending (glist).
void launchTileLists(const unsigned int* heads, const unsigned int* tile_idx,
                     const unsigned int* order, const std::uint8_t* voted, const unsigned int* vpos,
                     const unsigned int* gpos, int n, unsigned int* tile_begin, unsigned int* vlist,
                     unsigned int* glist, cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GROUND_TILES_CUH
