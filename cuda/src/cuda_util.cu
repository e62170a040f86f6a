#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <sstream>

#include "cuda_util.cuh"
#include "ground_filter/cuda_knn.h"

namespace ground_filter {
namespace cuda_impl {

void checkCuda(cudaError_t err, const char* call, const char* file, int line) {
  if (err == cudaSuccess) return;
  std::ostringstream os;
  os << "CUDA error " << cudaGetErrorName(err) << " (" << cudaGetErrorString(err) << ") in " << call
     << " at " << file << ":" << line;
  throw CudaError(cudaGetErrorName(err), os.str());
}

void parallelCopy(void* dst, const void* src, std::size_t bytes) {
  constexpr std::size_t kSlice = 1u << 20;
  if (bytes < 2 * kSlice) {
    std::memcpy(dst, src, bytes);
    return;
  }
  const std::int64_t slices = static_cast<std::int64_t>((bytes + kSlice - 1) / kSlice);
#pragma omp parallel for schedule(static)
  for (std::int64_t s = 0; s < slices; ++s) {
    const std::size_t b = static_cast<std::size_t>(s) * kSlice;
    std::memcpy(static_cast<char*>(dst) + b, static_cast<const char*>(src) + b,
                std::min(kSlice, bytes - b));
  }
}

}  // namespace cuda_impl
}  // namespace ground_filter
