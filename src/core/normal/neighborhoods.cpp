// Stages 2-3 of the normal filter: neighbour lists (through the KnnBackend), PCA of
// each neighbourhood, ground candidates.

#include "normal/neighborhoods.h"

#include <algorithm>
#include <cmath>

namespace ground_filter {
namespace normal {

std::size_t NeighborhoodStage::run(KnnBackend* search, const float* xyz, std::size_t len, int k,
                                   int threads, double min_planarity, double min_abs_nz,
                                   const double* lattice_var, NeighborLists* lists,
                                   std::uint8_t* candidate, StageTimes* times) {
  auto t0 = Clock::now();
  // The kd-tree decides each list's candidate flag right after the list (cache), with the eigen
  // solver only where the cheap decision is not certain (neighborhood_pca.h).
  CandidateTest test;
  test.min_planarity = min_planarity;
  test.min_abs_nz = min_abs_nz;
  if (lattice_var) std::copy(lattice_var, lattice_var + 3, test.lattice_var);
  if (search->searchWithCandidates(xyz, len, k, test, lists, candidate)) {
    const double search_ms = msSince(t0);
    const auto& parts = search->lastStageMs();
    for (const auto& e : parts) times->add(e.first, e.second);
    if (parts.empty()) times->add("knn", search_ms);
    std::size_t candidates = 0;
    for (std::size_t i = 0; i < len; ++i) candidates += candidate[i];
    return candidates;
  }
  // Others: the PCA of every list (the GPU's on the device), then the decision.
  const bool have_pca = search->searchWithPca(xyz, len, k, lists, &pca_);
  if (!have_pca) search->search(xyz, len, k, lists);
  const double search_ms = msSince(t0);
  const auto& parts = search->lastStageMs();
  for (const auto& e : parts) times->add(e.first, e.second);
  if (parts.empty()) times->add("knn", search_ms);

  t0 = Clock::now();
  NeighborListStore* kept = search->listStore();
  if (!have_pca && !(kept && kept->neighborhoodPca(&pca_))) {
    computeNeighborhoodPca(xyz, *lists, threads, &pca_);
  }
  std::size_t candidates = 0;
  const int nt = static_cast<int>(std::min<std::size_t>(threads, len / 8192 + 1));
#pragma omp parallel for num_threads(nt) schedule(static) reduction(+ : candidates)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(len); ++i) {
    const bool cand = isCandidatePca(pca_[i], min_planarity, min_abs_nz);
    candidate[i] = cand;
    candidates += cand;
  }
  times->add("pca", msSince(t0));
  return candidates;
}

}  // namespace normal
}  // namespace ground_filter
