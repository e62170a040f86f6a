// Stages 2-3 of the normal filter: neighbour lists (through the NeighborSearch backend), PCA of
// each neighbourhood, ground candidates.

#include "neighborhoods.h"

#include <algorithm>
#include <cmath>

namespace ground_filter {
namespace normal {

bool isFlat(const PointPca& r, double min_planarity) {
  // sigma_i = sqrt(lambda_i), sigma_1 >= sigma_2 >= sigma_3: linearity (s1 - s2)/s1, planarity
  // (s2 - s3)/s1, scattering s3/s1.
  const double s1 = std::sqrt(static_cast<double>(r.eigen[2]));
  const double s2 = std::sqrt(static_cast<double>(r.eigen[1]));
  const double s3 = std::sqrt(static_cast<double>(r.eigen[0]));
  if (!(s1 > 0.0)) return false;
  const double linear = (s1 - s2) / s1, planar = (s2 - s3) / s1, scatter = s3 / s1;
  return planar >= linear && planar >= scatter && planar >= min_planarity;
}

std::size_t NeighborhoodStage::run(NeighborSearch* search, const float* xyz, std::size_t len, int k,
                                   int threads, double min_planarity, double min_abs_nz,
                                   std::uint8_t* candidate, StageTimes* times) {
  auto t0 = Clock::now();
  // The kd-tree computes each list's PCA right after the list (cache); others do it after.
  const bool have_pca = search->searchWithPca(xyz, len, k, &lists_, &pca_);
  if (!have_pca) search->search(xyz, len, k, &lists_);
  const double search_ms = msSince(t0);
  const auto parts = search->lastStageMs();
  for (const auto& e : parts) times->add(e.first, e.second);
  if (parts.empty()) times->add("knn", search_ms);

  t0 = Clock::now();
  if (!have_pca && !search->neighborhoodPca(&pca_)) {
    computeNeighborhoodPca(xyz, lists_, threads, &pca_);
  }
  std::size_t candidates = 0;
  const int nt = static_cast<int>(std::min<std::size_t>(threads, len / 8192 + 1));
#pragma omp parallel for num_threads(nt) schedule(static) reduction(+ : candidates)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(len); ++i) {
    const PointPca& r = pca_[i];
    const bool flat = r.valid && isFlat(r, min_planarity);
    const bool cand = flat && std::abs(r.normal[2]) >= min_abs_nz;
    candidate[i] = cand;
    candidates += cand;
  }
  times->add("pca", msSince(t0));
  return candidates;
}

}  // namespace normal
}  // namespace ground_filter
