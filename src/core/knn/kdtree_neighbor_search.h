#ifndef GROUND_FILTER_SRC_CORE_KNN_KDTREE_NEIGHBOR_SEARCH_H
#define GROUND_FILTER_SRC_CORE_KNN_KDTREE_NEIGHBOR_SEARCH_H

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "knn/knn_backend.h"
#include "knn/neighborhood_pca.h"

namespace ground_filter {

/// \brief CPU K-nearest-neighbour search: an own kd-tree over the cloud (built in parallel),
///        queries in parallel (OpenMP) with AVX-512 or AVX2 when the CPU has it (and the SIMD
///        level in force, simd.h, allows it), exact results.
///
/// Each row is the K smallest (squared distance, point index) pairs in that order: ties at equal
/// distance keep the lower point index, so the lists are unique and the same for any thread
/// count and on every SIMD level (portable, AVX2, AVX-512). Squared distances are float `(dx*dx +
/// dy*dy) + dz*dz` without fused multiply-adds. The tree and scratch memory are kept between calls.
class KdTreeNeighborSearch : public KnnBackend, public NeighborListStore {
 public:
  /// \brief `threads` build and query threads (0 = all cores); `leaf_size` most points per
  ///        kd-tree leaf.
  explicit KdTreeNeighborSearch(int threads = 0, int leaf_size = 64);
  ~KdTreeNeighborSearch() override;

  /// \brief See NeighborSearch::search(); throws std::invalid_argument above 2^31 - 1 points.
  void search(const float* xyz, std::size_t n, int k, NeighborLists* out) override;
  std::string name() const override { return "kdtree"; }
  /// \brief Queries and PCA interleaved chunk by chunk (same results as search() followed by
  ///        computeNeighborhoodPca()); always true.
  bool searchWithPca(const float* xyz, std::size_t n, int k, NeighborLists* out,
                     std::vector<PointPca>* pca) override;
  /// \brief Queries and candidate flags interleaved chunk by chunk (computeRowsCandidates():
  ///        the same bytes as searchWithPca() followed by isCandidatePca()); always true.
  bool searchWithCandidates(const float* xyz, std::size_t n, int k, const CandidateTest& test,
                            NeighborLists* out, std::uint8_t* candidate) override;
  /// \brief How the last searchWithCandidates() decided its points (how many took the exact
  ///        Eigen path: `exact`).
  const CandidateCounts& lastCandidateCounts() const { return counts_; }
  /// \brief {"kdtree_build", "knn"} and, after searchWithPca() or searchWithCandidates(),
  ///        "pca": the query wall time split by the threads' time in each part.
  const std::vector<std::pair<std::string, double>>& lastStageMs() const override;

  /// \brief Itself: it keeps the lists of searchWithPca() and searchWithCandidates().
  NeighborListStore* listStore() override { return this; }
  /// \brief With `keep` true, searchWithPca() and searchWithCandidates() keep the lists
  ///        themselves (rows in tree order, indices only: no scattered writes) and leave
  ///        `out->indices`/`sq_dists` empty; countFlaggedNeighbors() then counts on them.
  ///        search() always fills `out`.
  /// \return `keep`.
  bool keepLists(bool keep) override;
  bool keptRows(const std::int32_t** rows, const std::uint32_t** points) const override;
  /// \brief See NeighborListStore::countFlaggedNeighbors(); false unless the last call was a
  ///        searchWithPca() or searchWithCandidates() with kept lists (of at least K points).
  bool countFlaggedNeighbors(const std::uint8_t* flags, std::uint16_t* flagged,
                             std::uint16_t* neighbors) override;
  /// \brief The kept lists of the last searchWithPca() in input order (distances recomputed
  ///        from the cloud, which must still be alive), for tests; false when none are kept.
  bool keptLists(NeighborLists* out) const;

  /// \brief Wall time of the tree build in the last search() [ms].
  double lastBuildMs() const { return build_ms_; }
  /// \brief Wall time of the queries in the last search() [ms] (without the PCA part).
  double lastQueryMs() const { return query_ms_; }
  /// \brief Whether search() may use the AVX-512 code (default: when the CPU has it; the SIMD
  ///        level in force must allow it too).
  bool usesAvx512() const { return use_avx512_; }
  /// \brief Turns the AVX-512 code off (the AVX2 or portable code then runs, as the SIMD level
  ///        allows; same lists) or back on where the CPU has it; for tests and benchmarks.
  void setUseAvx512(bool use);

 private:
  struct Impl;
  void run(const float* xyz, std::size_t n, int k, NeighborLists* out, std::vector<PointPca>* pca,
           const CandidateTest* test = nullptr, std::uint8_t* candidate = nullptr);
  // run()'s queries on the built tree, chunk by chunk in parallel, each chunk's PCA or candidate
  // flags right after its lists (`kept`: rows in tree order into impl_->rows).
  void queryChunks(const float* xyz, std::size_t kk, bool kept, NeighborLists* out,
                   std::vector<PointPca>* pca, const CandidateTest* test, std::uint8_t* candidate,
                   int threads);
  std::unique_ptr<Impl> impl_;
  int threads_;
  int leaf_size_;
  bool use_avx512_;
  bool has_avx2_;  // the CPU runs the AVX2 code (used below the AVX-512 code, or without it)
  double build_ms_ = 0.0;
  double query_ms_ = 0.0;
  double pca_ms_ = 0.0;
  bool with_pca_ = false;
  CandidateCounts counts_;   // of the last searchWithCandidates()
  bool keep_lists_ = false;  // keepLists()
  bool lists_kept_ = false;  // the last call's lists are in impl_->rows
  // lastStageMs(): refilled in place (short names, no allocation after the first call)
  mutable std::vector<std::pair<std::string, double>> stage_ms_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_KNN_KDTREE_NEIGHBOR_SEARCH_H
