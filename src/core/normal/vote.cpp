// Stage 4 of the normal filter: the naive-Bayes neighbourhood vote.

#include "normal/vote.h"

#include <algorithm>

namespace ground_filter {
namespace normal {

void VoteStage::run(NeighborListStore* kept, const NeighborLists& lists,
                    const std::uint8_t* candidate, std::size_t len, std::size_t candidates,
                    bool bayes, int threads, std::uint8_t* voted) {
  if (!bayes) {
    std::copy_n(candidate, len, voted);
    return;
  }
  // Naive-Bayes vote (paper): classes U (candidates) and V (the rest) of this neighbourhood set,
  // priors P(U) = U/N and P(V) = V/N; likelihood of a point's neighbourhood under U is the share
  // u/m of candidates among its m neighbours, under V it is (m - u)/m. Ground when
  // P(U) u/m > P(V) (m - u)/m, i.e. U u > V (m - u).
  const double U = static_cast<double>(candidates);
  const double V = static_cast<double>(len - candidates);
  const int nt = static_cast<int>(std::min<std::size_t>(threads, len / 4096 + 1));
  flagged_.resize(len);
  size_.resize(len);
  if (kept && kept->countFlaggedNeighbors(candidate, flagged_.data(), size_.data())) {
    // u and m counted where the lists are (GPU, kd-tree rows); same rule as below.
#pragma omp parallel for num_threads(nt) schedule(static, 4096)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(len); ++i) {
      const int u = flagged_[i], m = size_[i];
      voted[i] = U * u > V * (m - u);
    }
    return;
  }
  const int k = lists.k;
#pragma omp parallel for num_threads(nt) schedule(static, 4096)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(len); ++i) {
    const std::int32_t* row = &lists.indices[static_cast<std::size_t>(i) * k];
    int m = 0, u = 0;
    for (; m < k && row[m] >= 0; ++m) u += candidate[row[m]];
    voted[i] = U * u > V * (m - u);
  }
}

}  // namespace normal
}  // namespace ground_filter
