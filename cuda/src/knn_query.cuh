// Private: the KNN query kernel's launcher and its work counters.
#ifndef GROUND_FILTER_CUDA_SRC_KNN_QUERY_CUH
#define GROUND_FILTER_CUDA_SRC_KNN_QUERY_CUH

#include <cuda_runtime.h>

#include <cstdint>

#include "knn_grid.cuh"

namespace ground_filter {
namespace cuda_impl {

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
  kStatHeavy,
  kStatCount
};

/// Warps per heavy query in the second query kernel.
constexpr int kHeavyWarps = 16;

/// One warp per query for sorted points [base, end): row s of `out_idx` (and `out_d2` when not
/// null) gets the k nearest original indices of sorted point s. `run_stop`: per sorted point, the
/// end of its run of identical points (launchRunEnds), or null to skip no runs. `merge_min`: a
/// batch with at least this many entrants is merged into the list at once (0: never).
/// `abort_cands` > 0: a query whose cells hold more candidates is finished by kHeavyWarps warps
/// of one block in a second kernel (`heavy`: n entries, `heavy_count`: this call's counter, zero
/// before the call; `heavy_blocks` blocks). `stats` (kStatCount counters) may be null.
void launchKnnQuery(const GridDesc& g, const float4* pts, const unsigned long long* tkeys,
                    const uint2* tvals, const unsigned int* run_stop, int n, int base, int end,
                    int k, bool sort_cells, int merge_min, unsigned int abort_cands,
                    unsigned int* heavy, unsigned int* heavy_count, int heavy_blocks,
                    std::int32_t* out_idx, float* out_d2, unsigned long long* stats,
                    cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_KNN_QUERY_CUH
