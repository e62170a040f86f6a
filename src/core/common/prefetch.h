// Private to the core: software prefetch ahead of sequential passes.
#ifndef GROUND_FILTER_SRC_CORE_COMMON_PREFETCH_H
#define GROUND_FILTER_SRC_CORE_COMMON_PREFETCH_H

#include <cstddef>
#include <cstdint>

namespace ground_filter {

/// \brief Prefetches, for reading, the cache line `bytes` after `p`. The address may lie past
///        the end of p's array: it is formed as an integer and only prefetched, never read.
///        Sequential passes over large arrays use it: the hardware prefetcher of the
///        development VM did not keep up with them (docs/voxel_method.md, "Results").
inline void prefetchAhead(const void* p, std::size_t bytes) {
#if defined(__GNUC__)
  __builtin_prefetch(reinterpret_cast<const void*>(reinterpret_cast<std::uintptr_t>(p) + bytes));
#else
  (void)p;
  (void)bytes;
#endif
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_PREFETCH_H
