// Stage 6 of the normal filter: labels back in input order.

#include "classify.h"

#include "ground_filter/ground_filter.h"

namespace ground_filter {
namespace normal {

std::size_t classify(const std::vector<std::uint8_t>& ground,
                     const std::vector<std::uint32_t>& source, std::vector<std::uint8_t>* labels) {
  std::size_t count = 0;
  for (std::size_t j = 0; j < ground.size(); ++j) {
    if (ground[j]) {
      (*labels)[source[j]] = kGround;
      ++count;
    }
  }
  return count;
}

}  // namespace normal
}  // namespace ground_filter
