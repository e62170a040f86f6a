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
#include "knn_grid.cuh"
#include "knn_tuning.h"

namespace ground_filter {

struct CudaKnn::Impl {
  static constexpr int kMaxChunks = 16;
  CudaKnnOptions opt;
  CudaKnnTuning tune;             // experiment knobs (tests, benchmark): knn_tuning.h
  cudaStream_t stream = nullptr;  // all kernels
  cudaStream_t copy = nullptr;    // result downloads, overlapping the next query chunk
  cudaEvent_t kernel_done[kMaxChunks] = {};
  cudaEvent_t copy_done[kMaxChunks] = {};
  cudaEvent_t order_done = nullptr;
  std::string device_name;
  int sms = 1;  // multiprocessors
  std::size_t device_bytes = 0;
  CudaKnnTimings timings;
  CudaKnnQueryStats stats;  // with tune.collect_stats
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
  /// wait = false (lists kept on the device only): returns once the queries are launched, so
  /// the caller's next kernels queue behind them; the stream's next sync reports their errors.
  void searchOnDevice(const float* d_xyz, int n, int k, std::int32_t* indices, float* sq_dists,
                      bool wait = true);

  // The sections of searchOnDevice (cuda_knn.cu), in their order.
  /// Layout of `small` (device) and `h_small` (its host copy): bounds (7 ints), frame (5 floats:
  /// origin, edge, 1 / edge), level histogram (32 words), query counters (kStatCount).
  static constexpr std::size_t kSmallFrame = 32, kSmallHist = 64,
                               kSmallStats = 64 + 32 * sizeof(unsigned int);
  /// Grows every buffer of a search but the level tables; returns the bytes of `small`.
  std::size_t growSearchBuffers(std::size_t n, int k, bool dists);
  /// The Morton-sorted points of a search, on the device.
  struct SortedCloud {
    const unsigned long long* keys;  // sorted Morton keys
    const unsigned int* order;       // sorted -> original index
  };
  /// Bounds, Morton keys, sort, cell-start levels, duplicate runs; downloads `small` (and the
  /// row order when `download`). \throws std::invalid_argument for NaN/Inf points.
  SortedCloud sortPoints(const float* d_xyz, int n, bool download, std::size_t small_bytes);
  /// Level choice from the histogram and the cell tables of levels finest..0; returns the grid.
  cuda_impl::GridDesc buildGrid(const SortedCloud& sorted, int n, int k, bool download);
  /// The query kernel in chunks; with `indices`, each chunk downloads while the next computes and
  /// the host scatters its rows to their original places; waits for them unless `wait` is
  /// false with no download and no statistics.
  void runQueries(const cuda_impl::GridDesc& g, int n, int k, std::int32_t* indices,
                  float* sq_dists, bool wait);
  /// Reads the query counters into `stats` (tune.collect_stats).
  void readQueryStats(int n);

  void requireLists(const char* what) const {
    if (list_n == 0) {
      throw std::logic_error(std::string("CudaKnn::") + what +
                             ": no neighbour lists on the device (no successful search yet)");
    }
  }
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_KNN_IMPL_CUH
