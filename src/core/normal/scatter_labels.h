#ifndef GROUND_FILTER_SRC_CORE_NORMAL_SCATTER_LABELS_H
#define GROUND_FILTER_SRC_CORE_NORMAL_SCATTER_LABELS_H

#include <cstddef>
#include <cstdint>
#include <vector>

namespace ground_filter {
namespace normal {

/// \brief Stage 6 (labels in input order): kGround at input index source[j] for every ordered
///        point j with ground[j]; every other entry of `labels` is left as it is (kNonGround).
///        `threads` split the points (source is a permutation, so the result does not depend on
///        them).
/// \return the number of ground points.
std::size_t scatterLabels(const std::vector<std::uint8_t>& ground,
                          const std::vector<std::uint32_t>& source,
                          std::vector<std::uint8_t>* labels, int threads = 1);

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_SCATTER_LABELS_H
