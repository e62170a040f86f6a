// Private: the state of a CudaKnn (streams, persistent buffers, the lists kept on the device),
// shared by cuda_knn.cu and the whole-filter pipeline (cuda_normal_pipeline.cu).
#ifndef GROUND_FILTER_CUDA_SRC_KNN_IMPL_CUH
#define GROUND_FILTER_CUDA_SRC_KNN_IMPL_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>

#include "cuda_util.cuh"
#include "ground_filter/cuda_knn.h"

namespace ground_filter {

struct CudaKnn::Impl {
  static constexpr int kMaxChunks = 16;
  CudaKnnOptions opt;
  cudaStream_t stream = nullptr;  // all kernels
  cudaStream_t copy = nullptr;    // result downloads, overlapping the next query chunk
  cudaEvent_t kernel_done[kMaxChunks] = {};
  cudaEvent_t copy_done[kMaxChunks] = {};
  cudaEvent_t order_done = nullptr;
  std::string device_name;
  int sms = 1;  // multiprocessors
  std::size_t device_bytes = 0;
  CudaKnnTimings timings;
  // The lists of the last search, kept on the device (rows in Morton order).
  std::size_t list_n = 0;
  int list_k = 0;
  const float* list_xyz = nullptr;  // the points the lists index (device)

  cuda_impl::DeviceBuffer xyz, keys_a, keys_b, vals_a, vals_b, start_level, sorted, sort_temp,
      small, table_keys, table_vals, out_idx, out_d2, pca, flags, counts, run_id, run_end, run_stop,
      heavy, heavy_counts;
  cuda_impl::PinnedBuffer h_small, h_xyz, h_idx, h_d2, h_order, h_pca, h_flags, h_counts;

  /// Device bytes still allowed: the explicit limit, or 90 % of what is free now.
  std::size_t allowance() const {
    if (opt.memory_limit > 0) {
      return opt.memory_limit > device_bytes ? opt.memory_limit - device_bytes : 0;
    }
    std::size_t free_b = 0, total_b = 0;
    GF_CUDA_CHECK(cudaMemGetInfo(&free_b, &total_b));
    return free_b / 10 * 9;
  }

  /// Grows `buf` to `need` bytes unless that breaks the memory limit.
  void grow(cuda_impl::DeviceBuffer& buf, std::size_t need, const char* what) {
    if (need <= buf.bytes) return;
    const std::size_t extra = need + need / 8 - buf.bytes;
    if (opt.memory_limit > 0 && device_bytes + extra > opt.memory_limit) {
      std::ostringstream os;
      os << "CudaKnn: " << what << " needs " << (extra >> 20) << " MiB more device memory; the "
         << "memory limit is " << (opt.memory_limit >> 20) << " MiB (" << (device_bytes >> 20)
         << " MiB held)";
      throw CudaError("cudaErrorMemoryAllocation", os.str());
    }
    buf.ensure(need, &device_bytes);
  }

  /// Everything of search() after the points are on the device at `d_xyz` (n finite points):
  /// grid, queries; the lists stay on the device, and are downloaded when `indices` is set.
  void searchOnDevice(const float* d_xyz, int n, int k, std::int32_t* indices, float* sq_dists);

  void requireLists(const char* what) const {
    if (list_n == 0) {
      throw std::logic_error(std::string("CudaKnn::") + what +
                             ": no neighbour lists on the device (no successful search yet)");
    }
  }
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_KNN_IMPL_CUH
