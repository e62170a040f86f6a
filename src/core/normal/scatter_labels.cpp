// Stage 6 of the normal filter: labels back in input order.

#include "normal/scatter_labels.h"

#include <algorithm>
#include <cstdint>

#include "ground_filter/ground_filter.h"

namespace ground_filter {
namespace normal {

std::size_t scatterLabels(const std::vector<std::uint8_t>& ground,
                          const std::vector<std::uint32_t>& source,
                          std::vector<std::uint8_t>* labels, int threads) {
  std::size_t count = 0;
  // source is a permutation: the threads write distinct labels.
  const int nt = static_cast<int>(std::min<std::size_t>(threads, ground.size() / 32768 + 1));
#pragma omp parallel for num_threads(nt) schedule(static) reduction(+ : count)
  for (std::int64_t j = 0; j < static_cast<std::int64_t>(ground.size()); ++j) {
    if (ground[j]) {
      (*labels)[source[j]] = kGround;
      ++count;
    }
  }
  return count;
}

}  // namespace normal
}  // namespace ground_filter
