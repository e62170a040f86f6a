// Counts every operator new of the test binary that includes it (include it from one source file
// per binary only: it defines the global operator new and delete). Tests read allocationCount()
// before and after a scan to check that a filter allocates nothing once its buffers are sized.
#ifndef GROUND_FILTER_TEST_GF_TEST_ALLOC_COUNTER_H
#define GROUND_FILTER_TEST_GF_TEST_ALLOC_COUNTER_H

#include <atomic>
#include <cstddef>
#include <cstdlib>
#include <new>

namespace {
std::atomic<std::size_t>& allocationCount() {
  static std::atomic<std::size_t> count{0};
  return count;
}
}  // namespace

void* operator new(std::size_t size) {
  ++allocationCount();
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

#endif  // GROUND_FILTER_TEST_GF_TEST_ALLOC_COUNTER_H
