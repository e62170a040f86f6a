// Private: the kernels of the whole normal-vector filter on the device (compaction, grid-column
// order, PCA + candidates, naive-Bayes vote, tiles, RANSAC planes, distance test), as host
// launchers. Each mirrors a step of NormalGroundFilter::filter()
// (src/core/normal_ground_filter.cpp) operation by operation in double, so the labels equal the
// CPU's.
#ifndef GROUND_FILTER_CUDA_SRC_GROUND_KERNELS_CUH
#define GROUND_FILTER_CUDA_SRC_GROUND_KERNELS_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

namespace ground_filter {
namespace cuda_impl {

/// Scalar parameters of the device filter (see NormalGroundFilterParams).
struct GroundParamsDev {
  int k;
  int iterations;
  std::uint64_t seed;  // base seed of the RANSAC draws (CPU: ransacBaseSeed())
  double min_abs_nz;  // |n_z| of a candidate's normal, and of a plane's, at least
  double min_planarity;
  double plane_distance;
  double std_multiplier;
  double floor_share;      // sparse tile: lowest-level share that moves the cloud plane, 0 = off
  double floor_max_shift;  // sparse tile: largest move of the cloud plane [m]
  bool bayes_vote;
  bool std_filter;
  bool plane_all_points;
  bool local_planes;
};

/// Plane n . (p - o) + d = 0, as the CPU's Plane.
struct PlaneDev {
  double n[3];
  double d;
  double o[3];
  int valid;
};

/// Planes of at most this many voted points have their least-squares sums added in the CPU's
/// order (one thread, bit-identical); larger ones (big tiles, the cloud-wide plane) use
/// fixed-order parallel sums (deterministic; may differ from the CPU's sums in the last bits).
constexpr unsigned int kSerialRefineMax = 4096;

/// flags[i] = point i of the packed input is finite (i < n); flags[n] = 0.
void launchFiniteFlags(const float* in, int n, unsigned int* flags, cudaStream_t st);
/// Compacts the finite points (pos = exclusive scan of the flags): raw_xyz, raw_src (input
/// index); bounds[0..3] = min x, min y, max x, max y of them (ordered-int floats).
void launchCompact(const float* in, const unsigned int* flags, const unsigned int* pos, int n,
                   float* raw_xyz, unsigned int* raw_src, int* bounds, cudaStream_t st);
/// Morton key of the x/y grid column of every compacted point (CPU: cellIndex + spreadBits).
void launchColumnKeys(const float* raw_xyz, int n, double min_x, double min_y, double inv_cell,
                      unsigned long long* keys, unsigned int* vals, cudaStream_t st);
/// xyz[j] = raw_xyz[order[j]], src[j] = raw_src[order[j]].
void launchGatherColumns(const float* raw_xyz, const unsigned int* raw_src,
                         const unsigned int* order, int n, float* xyz, unsigned int* src,
                         cudaStream_t st);
/// PCA of every KNN row, flatness and normal test: cand[original index] (0/1); cand_count += them.
void launchPcaCandidates(const float* xyz, const float4* pts, const std::int32_t* rows, int n,
                         const GroundParamsDev& p, std::uint8_t* cand, unsigned int* cand_count,
                         cudaStream_t st);
/// Naive-Bayes vote over each KNN row (or a copy of cand without bayes_vote).
void launchVote(const float4* pts, const std::int32_t* rows, int n, const GroundParamsDev& p,
                const std::uint8_t* cand, const unsigned int* cand_count, std::uint8_t* voted,
                cudaStream_t st);
/// Tile key (tx << 32 | ty) of every point, 0 without local planes; vals = identity.
void launchTileKeys(const float* xyz, int n, bool local_planes, double min_x, double min_y,
                    double inv_tile, unsigned long long* keys, unsigned int* vals, cudaStream_t st);
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
/// RANSAC planes: item 0 the cloud-wide plane (when a tile has < 3 voted points or without
/// local planes; refined grid-wide when large), item 1 + t tile t. `work` and `need_global` are
/// zeroed counters, `partial` holds refinePartialBytes(); `tiles_max` bounds the tile count.
void launchPlanes(const float* xyz, const unsigned long long* sorted_keys,
                  const unsigned int* tile_begin, const unsigned int* ntiles,
                  const unsigned int* vpos, const unsigned int* vlist, const unsigned int* glist,
                  const unsigned int* gcount, const GroundParamsDev& p, PlaneDev* planes,
                  unsigned int* work, unsigned int* need_global, double* partial,
                  std::size_t tiles_max, int blocks, cudaStream_t st);
/// Bytes of the per-block partial sums of the grid-wide plane refinement.
std::size_t refinePartialBytes();
/// Distance test per tile: labels[src[i]] = 1 for ground; ground_count += them. `work` zeroed.
void launchClassify(const float* xyz, const unsigned int* src, const unsigned int* order,
                    const std::uint8_t* voted, const unsigned int* tile_begin,
                    const unsigned int* ntiles, const unsigned int* vpos, const unsigned int* vlist,
                    const GroundParamsDev& p, const PlaneDev* planes, std::uint8_t* labels,
                    unsigned int* ground_count, unsigned int* work, int blocks, cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GROUND_KERNELS_CUH
