// Private: experiment knobs of CudaKnn and its per-query work counters, for the GPU tests and the
// benchmark only (users set CudaKnnOptions). Host-clean: plain C++ compilers include it.
#ifndef GROUND_FILTER_CUDA_SRC_KNN_TUNING_H
#define GROUND_FILTER_CUDA_SRC_KNN_TUNING_H

#include <string>

#include "ground_filter/cuda_knn.h"

namespace ground_filter {

/// Knobs of the grid and the query kernel; the defaults are what every user gets.
struct CudaKnnTuning {
  int level_min_points = 0;     ///< grid level choice: own cell holds >= this many, 0 = K/4 [pts]
  bool sort_cells = true;       ///< visit each batch of cells nearest first [bool] (true)
  bool collect_stats = false;   ///< count per-query work in CudaKnnQueryStats (slower) [bool]
  int download_chunks = 0;      ///< query/download pipeline depth, 0 = auto (<= 16) [chunks] (0)
  bool skip_duplicates = true;  ///< skip runs of identical points that cannot enter [bool] (true)
  int merge_min = 6;            ///< merge a batch's entrants in one go from this many [pts] (6)
  int heavy_candidates = 8192;  ///< more candidates: query to 16 warps, 0 = never [pts] (8192)
};

/// Per-query work of the last search() (only with CudaKnnTuning::collect_stats).
struct CudaKnnQueryStats {
  double candidates_per_query = 0.0;  ///< points whose distance was computed
  double insertions_per_query = 0.0;  ///< list insertions
  double shells_per_query = 0.0;      ///< shells of cells visited
  double levels_per_query = 0.0;      ///< grid levels tried
  double mean_query_cycles = 0.0;     ///< SM clock cycles per query, mean
  double max_query_cycles = 0.0;      ///< the slowest query's cycles
  std::string detail;                 ///< slow-query summary
};

/// The tests' and the benchmark's way to a CudaKnn's knobs and counters (a friend of CudaKnn).
struct CudaKnnTuningAccess {
  /// Sets the knobs used by the next search().
  static void set(CudaKnn& knn, const CudaKnnTuning& tuning);
  /// The knobs in use.
  static const CudaKnnTuning& get(const CudaKnn& knn);
  /// Counters of the last search() (zeros without collect_stats).
  static const CudaKnnQueryStats& stats(const CudaKnn& knn);
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_KNN_TUNING_H
