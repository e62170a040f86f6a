#ifndef GROUND_FILTER_SRC_CORE_NORMAL_RADIX_SORT_H
#define GROUND_FILTER_SRC_CORE_NORMAL_RADIX_SORT_H

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace ground_filter {
namespace normal {

/// \brief Stable LSD radix sort of `order` (values 0..n-1) by `keys[order[i]]`; 8-bit digits,
///        passes whose digit is the same for every key are skipped. `scratch` is reused.
inline void radixSortByKey(const std::vector<std::uint64_t>& keys,
                           std::vector<std::uint32_t>* order, std::vector<std::uint32_t>* scratch) {
  const std::size_t n = keys.size();
  order->resize(n);
  for (std::size_t i = 0; i < n; ++i) (*order)[i] = static_cast<std::uint32_t>(i);
  if (n < 2) return;
  std::array<std::array<std::uint32_t, 256>, 8> hist{};
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t key = keys[i];
    for (int d = 0; d < 8; ++d) ++hist[d][(key >> (8 * d)) & 0xff];
  }
  scratch->resize(n);
  for (int d = 0; d < 8; ++d) {
    auto& h = hist[d];
    if (h[(keys[0] >> (8 * d)) & 0xff] == n) continue;  // all keys share this digit
    std::uint32_t sum = 0;
    for (auto& c : h) {
      const std::uint32_t c0 = c;
      c = sum;
      sum += c0;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t v = (*order)[i];
      (*scratch)[h[(keys[v] >> (8 * d)) & 0xff]++] = v;
    }
    order->swap(*scratch);
  }
}

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_RADIX_SORT_H
