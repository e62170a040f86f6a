// Private host helpers of ground_filter_cuda: CUDA error checks, growing device/pinned buffers,
// timing and copy helpers. Not installed; CUDA types allowed.
#ifndef GROUND_FILTER_CUDA_SRC_CUDA_UTIL_CUH
#define GROUND_FILTER_CUDA_SRC_CUDA_UTIL_CUH

#include <cuda_runtime.h>

#include <chrono>
#include <cstddef>

#include "common/threads_timing.h"

namespace ground_filter {
namespace cuda_impl {

/// Throws CudaError naming the failed call and the CUDA error (no-op on cudaSuccess).
void checkCuda(cudaError_t err, const char* call, const char* file, int line);

}  // namespace cuda_impl
}  // namespace ground_filter

#define GF_CUDA_CHECK(call) ::ground_filter::cuda_impl::checkCuda((call), #call, __FILE__, __LINE__)
// After a kernel launch: launch-configuration errors (asynchronous faults surface at the next
// synchronising call, which is checked too).
#define GF_CUDA_CHECK_LAUNCH() GF_CUDA_CHECK(cudaGetLastError())

namespace ground_filter {
namespace cuda_impl {

/// \brief Milliseconds since `t0` (the core's one definition).
using ::ground_filter::msSince;

/// Blocks of `threads` covering `n` items.
inline unsigned int blocksFor(std::size_t n, int threads) {
  return static_cast<unsigned int>((n + threads - 1) / threads);
}

/// memcpy over all cores for large blocks (one core copies far slower than PCIe delivers).
void parallelCopy(void* dst, const void* src, std::size_t bytes);

/// cudaMalloc / cudaFree.
struct DeviceAlloc {
  static cudaError_t alloc(void** p, std::size_t bytes) { return cudaMalloc(p, bytes); }
  static cudaError_t release(void* p) { return cudaFree(p); }
  static constexpr bool kDevice = true;
};
/// cudaMallocHost / cudaFreeHost (pinned host memory).
struct PinnedAlloc {
  static cudaError_t alloc(void** p, std::size_t bytes) { return cudaMallocHost(p, bytes); }
  static cudaError_t release(void* p) { return cudaFreeHost(p); }
  static constexpr bool kDevice = false;
};

/// A buffer that only grows (with 1/8 slack, so slowly growing scans do not reallocate);
/// `total`, when given, tracks the bytes held.
template <class Alloc>
struct Buffer {
  void* ptr = nullptr;
  std::size_t bytes = 0;
  Buffer() = default;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  ~Buffer() {
    if (ptr) Alloc::release(ptr);  // no throwing from a destructor
  }
  void ensure(std::size_t need, std::size_t* total = nullptr) {
    if (need <= bytes) return;
    if (ptr) {
      GF_CUDA_CHECK(Alloc::release(ptr));
      if (total) *total -= bytes;
      ptr = nullptr;
      bytes = 0;
    }
    const std::size_t want = need + need / 8;
    GF_CUDA_CHECK(Alloc::alloc(&ptr, want));
    bytes = want;
    if (total) *total += want;
  }
  template <class T>
  T* as() const {
    return static_cast<T*>(ptr);
  }
};

using DeviceBuffer = Buffer<DeviceAlloc>;
using PinnedBuffer = Buffer<PinnedAlloc>;

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_CUDA_UTIL_CUH
