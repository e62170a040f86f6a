#ifndef GROUND_FILTER_SRC_CORE_COMMON_HUGE_PAGES_H
#define GROUND_FILTER_SRC_CORE_COMMON_HUGE_PAGES_H

// Large per-scan buffers on transparent huge pages where the kernel leaves that to the program
// (THP "madvise", the Debian and Ubuntu default): the random passes over multi-megabyte arrays
// (radix scatter, gathers in key order) miss the TLB less. Elsewhere a plain resize.

#if defined(__linux__)
#include <sys/mman.h>
#endif

#include <cstddef>
#include <cstdint>

namespace ground_filter {

/// \brief Buffers that grow to at least this many bytes are advised as huge pages.
constexpr std::size_t kHugeBufferMinBytes = std::size_t{16} << 20;

/// \brief `v->resize(n)` for a std::vector-like buffer whose old contents are not needed. When
///        it must grow to kHugeBufferMinBytes or more, it is reallocated empty, the new block is
///        advised as huge pages (madvise(MADV_HUGEPAGE), a hint: a kernel without THP ignores or
///        refuses it) and only then filled, so the first touch takes huge pages.
template <class Vector>
void resizeScratch(Vector* v, std::size_t n) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  using T = typename Vector::value_type;
  if (n > v->capacity() && n * sizeof(T) >= kHugeBufferMinBytes) {
    constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
    Vector().swap(*v);
    v->reserve(n);
    const auto b = reinterpret_cast<std::uintptr_t>(v->data());
    const std::uintptr_t lo = (b + kHuge - 1) & ~(kHuge - 1);
    const std::uintptr_t hi = (b + n * sizeof(T)) & ~(kHuge - 1);
    if (hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
  }
#endif
  v->resize(n);
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_HUGE_PAGES_H
