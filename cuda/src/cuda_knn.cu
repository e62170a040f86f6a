// CudaKnn: exact K-nearest-neighbour search on the GPU over a hashed multi-level uniform grid.
//
// One search() (two streams: kernels, and downloads that overlap them):
//   upload -> bounds -> Morton keys (21 bits per axis over the bounding cube) -> radix sort ->
//   per-point "coarsest level at which this point starts a new cell" + histogram -> [sync: level
//   choice on the host] -> one hash table per level (cell key -> first point, count) -> one warp
//   per query, in chunks of Morton-ordered rows -> each chunk downloads while the next computes,
//   and the host scatters its rows to their original places.
// Sorting along the Morton curve makes every cell of every power-of-two level a contiguous range
// of the sorted points, so a single sort serves all levels. The lists stay on the device for
// neighborhoodPca() and countFlaggedNeighbors().
//
// Kernel families live in their own files: knn_grid (grid construction), knn_query (the query
// kernel), knn_pca (PCA and vote counts); cuda_util holds the host helpers.

#include <cuda_runtime.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "cuda_util.cuh"
#include "ground_filter/cuda_knn.h"
#include "knn_grid.cuh"
#include "knn_impl.cuh"
#include "knn_pca.cuh"
#include "knn_query.cuh"

namespace ground_filter {

using namespace cuda_impl;  // NOLINT: private .cu file

namespace {

/// Start-up probe: proves that this build's device code runs on the device.
__global__ void probeKernel(int* out) { *out = 42; }

}  // namespace

bool CudaKnn::deviceAvailable(std::string* why, int device) {
  int count = 0;
  cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess) {
    if (why) {
      // The CUDA error's name first (CudaError::errorName()). No GPU, or no NVIDIA driver at
      // all: the runtime then says "CUDA driver version is insufficient"
      // (cudaErrorInsufficientDriver, driver version 0), which reads like an old driver. Only a
      // driver that is there and too old gets that wording.
      int driver = 0;
      cudaDriverGetVersion(&driver);
      if (err == cudaErrorNoDevice || (err == cudaErrorInsufficientDriver && driver == 0)) {
        *why = std::string(cudaGetErrorName(err)) + ": no CUDA device on this machine" +
               (driver == 0 ? " (no NVIDIA driver loaded)" : "");
      } else if (err == cudaErrorInsufficientDriver) {
        int runtime = 0;
        cudaRuntimeGetVersion(&runtime);
        *why = std::string(cudaGetErrorName(err)) + ": the NVIDIA driver supports CUDA " +
               std::to_string(driver / 1000) + "." + std::to_string(driver % 1000 / 10) +
               ", this build needs " + std::to_string(runtime / 1000) + "." +
               std::to_string(runtime % 1000 / 10) + " (update the driver)";
      } else {
        *why = std::string(cudaGetErrorName(err)) + ": " + cudaGetErrorString(err);
      }
    }
    cudaGetLastError();  // clear
    return false;
  }
  if (device < 0 || device >= count) {
    if (why) {
      *why = "cudaErrorInvalidDevice: device " + std::to_string(device) + " requested, " +
             std::to_string(count) + " present";
    }
    return false;
  }
  cudaDeviceProp prop;
  err = cudaGetDeviceProperties(&prop, device);
  if (err != cudaSuccess) {
    if (why) *why = std::string(cudaGetErrorName(err)) + ": " + cudaGetErrorString(err);
    cudaGetLastError();
    return false;
  }
  if (prop.major * 10 + prop.minor < 75) {
    if (why) {
      *why = "cudaErrorNoKernelImageForDevice: " + std::string(prop.name) + " is sm_" +
             std::to_string(prop.major * 10 + prop.minor) + ", this build needs sm_75 or newer";
    }
    return false;
  }
  // Run a kernel: catches a device this build has no code for, or a broken driver.
  err = cudaSetDevice(device);
  int* d_probe = nullptr;
  int h_probe = 0;
  if (err == cudaSuccess) err = cudaMalloc(&d_probe, sizeof(int));
  if (err == cudaSuccess) {
    probeKernel<<<1, 1>>>(d_probe);
    err = cudaGetLastError();
    if (err == cudaSuccess) {
      err = cudaMemcpy(&h_probe, d_probe, sizeof(int), cudaMemcpyDeviceToHost);
    }
    cudaFree(d_probe);
  }
  if (err == cudaSuccess && h_probe != 42) err = cudaErrorUnknown;
  if (err != cudaSuccess) {
    if (why) *why = std::string(cudaGetErrorName(err)) + ": " + cudaGetErrorString(err);
    cudaGetLastError();
    return false;
  }
  if (why) why->clear();
  return true;
}

CudaKnn::CudaKnn(const CudaKnnOptions& options) : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  im.opt = options;
  std::string why;
  if (!deviceAvailable(&why, options.device)) {
    const std::string name = why.substr(0, why.find(':'));
    throw CudaError(name, "CudaKnn: no usable CUDA device: " + why);
  }
  GF_CUDA_CHECK(cudaSetDevice(options.device));
  cudaDeviceProp prop;
  GF_CUDA_CHECK(cudaGetDeviceProperties(&prop, options.device));
  im.device_name = prop.name;
  im.sms = prop.multiProcessorCount;
  GF_CUDA_CHECK(cudaStreamCreateWithFlags(&im.stream, cudaStreamNonBlocking));
  GF_CUDA_CHECK(cudaStreamCreateWithFlags(&im.copy, cudaStreamNonBlocking));
  for (int c = 0; c < Impl::kMaxChunks; ++c) {
    GF_CUDA_CHECK(cudaEventCreateWithFlags(&im.kernel_done[c], cudaEventDisableTiming));
    GF_CUDA_CHECK(cudaEventCreateWithFlags(&im.copy_done[c], cudaEventDisableTiming));
  }
  GF_CUDA_CHECK(cudaEventCreateWithFlags(&im.order_done, cudaEventDisableTiming));
}

CudaKnn::~CudaKnn() {
  if (!impl_) return;
  Impl& im = *impl_;
  if (im.stream) cudaStreamSynchronize(im.stream);
  if (im.copy) cudaStreamSynchronize(im.copy);
  for (int c = 0; c < Impl::kMaxChunks; ++c) {
    if (im.kernel_done[c]) cudaEventDestroy(im.kernel_done[c]);
    if (im.copy_done[c]) cudaEventDestroy(im.copy_done[c]);
  }
  if (im.order_done) cudaEventDestroy(im.order_done);
  if (im.stream) cudaStreamDestroy(im.stream);
  if (im.copy) cudaStreamDestroy(im.copy);
}

const CudaKnnTimings& CudaKnn::lastTimings() const { return impl_->timings; }
std::string CudaKnn::deviceName() const { return impl_->device_name; }
std::size_t CudaKnn::deviceBytes() const { return impl_->device_bytes; }

void CudaKnn::search(const float* xyz, std::size_t n_in, int k, std::int32_t* indices,
                     float* sq_dists) {
  Impl& im = *impl_;
  im.timings = CudaKnnTimings();
  im.stats = CudaKnnQueryStats();
  im.list_n = 0;
  const auto t_start = std::chrono::steady_clock::now();
  if (k < 1 || k > kMaxK) {
    throw std::invalid_argument("CudaKnn::search: k = " + std::to_string(k) +
                                " is out of range [1, " + std::to_string(kMaxK) + "]");
  }
  if (n_in >= (1u << 31) - 1) {
    throw std::invalid_argument("CudaKnn::search: " + std::to_string(n_in) +
                                " points exceed the 2^31 - 1 that int32 indices address");
  }
  if (n_in == 0) return;
  if (!xyz) throw std::invalid_argument("CudaKnn::search: null xyz");
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  im.grow(im.xyz, n_in * 3 * sizeof(float), "the point copy");

  // ---- upload
  auto t0 = std::chrono::steady_clock::now();
  const std::size_t in_bytes = n_in * 3 * sizeof(float);
  im.h_xyz.ensure(in_bytes);
  parallelCopy(im.h_xyz.ptr, xyz, in_bytes);
  GF_CUDA_CHECK(
      cudaMemcpyAsync(im.xyz.ptr, im.h_xyz.ptr, in_bytes, cudaMemcpyHostToDevice, im.stream));
  GF_CUDA_CHECK(cudaStreamSynchronize(im.stream));
  const double upload_ms = msSince(t0);
  im.searchOnDevice(im.xyz.as<float>(), static_cast<int>(n_in), k, indices, sq_dists);
  im.timings.upload_ms = upload_ms;
  im.timings.total_ms = msSince(t_start);
}

void CudaKnn::Impl::searchOnDevice(const float* d_xyz, int n, int k, std::int32_t* indices,
                                   float* sq_dists, bool wait) {
  list_n = 0;
  const bool download = indices != nullptr;
  const auto t_start = std::chrono::steady_clock::now();
  const std::size_t small_bytes = growSearchBuffers(static_cast<std::size_t>(n), k, sq_dists);
  auto t0 = std::chrono::steady_clock::now();
  const SortedCloud sorted_cloud = sortPoints(d_xyz, n, download, small_bytes);
  const GridDesc g = buildGrid(sorted_cloud, n, k, download);
  timings.grid_ms = msSince(t0);
  t0 = std::chrono::steady_clock::now();
  runQueries(g, n, k, indices, sq_dists, wait);
  timings.query_ms = msSince(t0);  // with the overlapped download and scatter (if it waits)
  list_n = static_cast<std::size_t>(n);
  list_k = k;
  list_xyz = d_xyz;
  if (tune.collect_stats) readQueryStats(n);
  timings.total_ms = msSince(t_start);
}

// ---- buffers for everything but the level tables
std::size_t CudaKnn::Impl::growSearchBuffers(std::size_t n_in, int k, bool dists) {
  const int n = static_cast<int>(n_in);
  const std::size_t rows = n_in * static_cast<std::size_t>(k);
  std::size_t sort_temp_bytes = 0;
  {
    cub::DoubleBuffer<unsigned long long> kb(nullptr, nullptr);
    cub::DoubleBuffer<unsigned int> vb(nullptr, nullptr);
    GF_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, sort_temp_bytes, kb, vb, n, 0,
                                                  3 * kCoordBits, stream));
    std::size_t scan_bytes = 0;
    GF_CUDA_CHECK(cub::DeviceScan::InclusiveSum(nullptr, scan_bytes,
                                                static_cast<unsigned int*>(nullptr),
                                                static_cast<unsigned int*>(nullptr), n, stream));
    sort_temp_bytes = std::max(sort_temp_bytes, scan_bytes);
  }
  grow(keys_a, n_in * sizeof(unsigned long long), "the Morton keys");
  grow(keys_b, n_in * sizeof(unsigned long long), "the Morton keys");
  grow(vals_a, n_in * sizeof(unsigned int), "the sort order");
  grow(vals_b, n_in * sizeof(unsigned int), "the sort order");
  grow(start_level, n_in, "the cell starts");
  grow(sorted, n_in * sizeof(float4), "the sorted points");
  grow(sort_temp, sort_temp_bytes, "the sort scratch");
  grow(run_id, n_in * sizeof(unsigned int), "the duplicate runs");
  grow(run_end, n_in * sizeof(unsigned int), "the duplicate runs");
  grow(run_stop, n_in * sizeof(unsigned int), "the duplicate runs");
  if (tune.heavy_candidates > 0) {
    grow(heavy, n_in * sizeof(unsigned int), "the heavy queries");
    grow(heavy_counts, kMaxChunks * sizeof(unsigned int), "the heavy queries");
  }
  const std::size_t small_bytes = kSmallStats + kStatCount * sizeof(unsigned long long);
  grow(small, small_bytes, "the bounds");
  grow(out_idx, rows * sizeof(std::int32_t), "the neighbour indices");
  if (dists) grow(out_d2, rows * sizeof(float), "the neighbour distances");
  h_small.ensure(small_bytes);
  return small_bytes;
}

// ---- bounds, keys, sort, cell-start levels
CudaKnn::Impl::SortedCloud CudaKnn::Impl::sortPoints(const float* d_xyz, int n, bool download,
                                                     std::size_t small_bytes) {
  const std::size_t n_in = static_cast<std::size_t>(n);
  cudaStream_t st = stream;
  char* d_small = small.as<char>();
  int* d_bounds = reinterpret_cast<int*>(d_small);                   // 7 ints
  float* d_frame = reinterpret_cast<float*>(d_small + kSmallFrame);  // 5 floats
  unsigned int* d_hist = reinterpret_cast<unsigned int*>(d_small + kSmallHist);
  launchBoundsAndFrame(d_xyz, n, d_bounds, d_frame, st);
  launchMorton(d_xyz, n, d_frame, keys_a.as<unsigned long long>(), vals_a.as<unsigned int>(), st);
  cub::DoubleBuffer<unsigned long long> kb(keys_a.as<unsigned long long>(),
                                           keys_b.as<unsigned long long>());
  cub::DoubleBuffer<unsigned int> vb(vals_a.as<unsigned int>(), vals_b.as<unsigned int>());
  std::size_t temp_bytes = sort_temp.bytes;
  GF_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(
      sort_temp.ptr, temp_bytes, kb, vb, n, 3 * (kCoordBits - kSortedLevels), 3 * kCoordBits, st));
  const SortedCloud out{kb.Current(), vb.Current()};
  GF_CUDA_CHECK(cudaMemsetAsync(
      d_hist, 0, 32 * sizeof(unsigned int) + kStatCount * sizeof(unsigned long long), st));
  if (tune.heavy_candidates > 0) {
    GF_CUDA_CHECK(cudaMemsetAsync(heavy_counts.ptr, 0, kMaxChunks * sizeof(unsigned int), st));
  }
  launchCellStartLevel(out.keys, n, start_level.as<unsigned char>(), d_hist, st);
  launchGather(d_xyz, out.order, n, sorted.as<float4>(), st);
  {  // runs of identical points (their indices ascend): the query skips the rest of a run
     // once one member cannot enter its list
    unsigned int* d_run_id = run_id.as<unsigned int>();
    unsigned int* d_run_end = run_end.as<unsigned int>();
    launchRunHeads(sorted.as<float4>(), n, d_run_end, st);  // heads, for the scan
    std::size_t scan_bytes = sort_temp.bytes;
    GF_CUDA_CHECK(
        cub::DeviceScan::InclusiveSum(sort_temp.ptr, scan_bytes, d_run_end, d_run_id, n, st));
    launchRunEnds(sorted.as<float4>(), d_run_id, n, d_run_end, run_stop.as<unsigned int>(), st);
  }
  if (download) {  // the row order (sorted -> original) for the host-side scatter
    h_order.ensure(n_in * sizeof(unsigned int));
    GF_CUDA_CHECK(cudaEventRecord(order_done, st));
    GF_CUDA_CHECK(cudaStreamWaitEvent(copy, order_done, 0));
    GF_CUDA_CHECK(cudaMemcpyAsync(h_order.ptr, out.order, n_in * sizeof(unsigned int),
                                  cudaMemcpyDeviceToHost, copy));
  }
  GF_CUDA_CHECK(cudaMemcpyAsync(h_small.ptr, small.ptr, small_bytes, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  const int* h_bounds = h_small.as<int>();
  if (h_bounds[6] > 0) {
    GF_CUDA_CHECK(cudaStreamSynchronize(copy));
    throw std::invalid_argument("CudaKnn::search: " + std::to_string(h_bounds[6]) + " of " +
                                std::to_string(n) +
                                " points have NaN/Inf coordinates; remove them first");
  }
  return out;
}

// ---- level choice: cells per level m_b = points starting a cell at level <= b
GridDesc CudaKnn::Impl::buildGrid(const SortedCloud& sorted_cloud, int n, int k, bool download) {
  const std::size_t n_in = static_cast<std::size_t>(n);
  const float* h_frame = reinterpret_cast<const float*>(h_small.as<char>() + kSmallFrame);
  const unsigned int* h_hist =
      reinterpret_cast<const unsigned int*>(h_small.as<char>() + kSmallHist);
  std::size_t cells[kMaxLevels];
  std::size_t acc = 0;
  for (int b = 0; b < kMaxLevels; ++b) {
    acc += h_hist[b];
    cells[b] = acc;
  }
  // Finest level: where cells average <= ~1.7 points (finer levels would be nearly empty), at
  // most the finest that the sort orders (kSortedLevels).
  int finest = kSortedLevels;
  for (int b = 0; b < kSortedLevels; ++b) {
    if (cells[b] * 10 >= n_in * 6) {
      finest = b;
      break;
    }
  }
  GridDesc g;
  std::memset(&g, 0, sizeof g);
  g.ox = h_frame[0];
  g.oy = h_frame[1];
  g.oz = h_frame[2];
  g.inv = h_frame[4];
  const float edge = h_frame[3];
  // Rounding slack: a few float ulps of the largest coordinate magnitude involved.
  const float mag = std::max({std::fabs(g.ox), std::fabs(g.oy), std::fabs(g.oz)}) + edge;
  g.eps = 8.f * std::numeric_limits<float>::epsilon() * mag;
  const int min_pts_auto = std::max(1, std::min(k, n) / 4);
  g.min_points = tune.level_min_points > 0 ? tune.level_min_points : min_pts_auto;

  // Tables for levels finest..0; under a memory limit, drop the finest levels first.
  auto log2Cap = [&](int b) {
    unsigned int l2 = 5;
    while ((std::size_t(1) << l2) < 2 * cells[b]) ++l2;
    return l2;
  };
  auto tableSlots = [&](int fin) {
    std::size_t s = 0;
    for (int b = fin; b >= 0; --b) s += std::size_t(1) << log2Cap(b);
    return s;
  };
  const std::size_t slot_bytes = sizeof(unsigned long long) + sizeof(uint2);
  auto tableBytes = [&](int fin) { return tableSlots(fin) * slot_bytes * 9 / 8; };
  const std::size_t held = table_keys.bytes + table_vals.bytes;
  // The free memory is asked for only when the tables must grow (the same levels: what fits
  // in the tables held fits in them plus the allowance): cudaMemGetInfo took 50 us a KITTI
  // frame, with the GPU idle meanwhile (docs/gpu.md, "The host side, traced").
  if (tableBytes(finest) > held) {
    const std::size_t allow = allowance() + held;
    while (finest > 0 && tableBytes(finest) > allow) --finest;
  }
  g.nlev = finest + 1;
  std::size_t off = 0;
  for (int l = 0; l < g.nlev; ++l) {
    const int b = finest - l;
    LevelDesc& lv = g.lv[l];
    lv.bits = b;
    lv.cell = edge / static_cast<float>(1u << b);
    lv.log2cap = log2Cap(b);
    lv.table_off = off;
    off += std::size_t(1) << lv.log2cap;
  }
  grow(table_keys, off * sizeof(unsigned long long), "the grid cell tables");
  grow(table_vals, off * sizeof(uint2), "the grid cell tables");
  unsigned long long* d_tkeys = table_keys.as<unsigned long long>();
  GF_CUDA_CHECK(cudaMemsetAsync(d_tkeys, 0xff, off * sizeof(unsigned long long), stream));
  launchBuildCells(g, sorted_cloud.keys, start_level.as<unsigned char>(), n, d_tkeys,
                   table_vals.as<uint2>(), stream);
  if (download || tune.collect_stats) {  // the pipeline needs no sync here
    GF_CUDA_CHECK(cudaStreamSynchronize(stream));
  }
  timings.levels = g.nlev;
  timings.finest_bits = finest;
  return g;
}

// ---- queries in chunks of Morton-ordered rows; each chunk's rows download while the next
//      chunk computes, and the host scatters them to their original rows meanwhile.
void CudaKnn::Impl::runQueries(const GridDesc& g, int n, int k, std::int32_t* indices,
                               float* sq_dists, bool wait) {
  const bool download = indices != nullptr;
  const std::size_t rows = static_cast<std::size_t>(n) * static_cast<std::size_t>(k);
  cudaStream_t st = stream;
  const int auto_chunks = std::max(1, std::min(kMaxChunks, (n + 32767) / 32768));
  const int chunks =
      !download
          ? 1
          : (tune.download_chunks > 0 ? std::min(tune.download_chunks, kMaxChunks) : auto_chunks);
  const int per_chunk = (n + chunks - 1) / chunks;
  std::int32_t* d_idx = out_idx.as<std::int32_t>();
  float* d_d2 = sq_dists ? out_d2.as<float>() : nullptr;
  unsigned long long* d_stats =
      tune.collect_stats ? reinterpret_cast<unsigned long long*>(small.as<char>() + kSmallStats)
                         : nullptr;
  if (download) {
    h_idx.ensure(rows * sizeof(std::int32_t));
    if (sq_dists) h_d2.ensure(rows * sizeof(float));
  }
  for (int c = 0; c < chunks; ++c) {
    const int b = c * per_chunk, e = std::min(n, b + per_chunk);
    if (b >= e) break;
    const bool use_heavy = tune.heavy_candidates > 0;
    launchKnnQuery(
        g, sorted.as<float4>(), table_keys.as<unsigned long long>(), table_vals.as<uint2>(),
        tune.skip_duplicates ? run_stop.as<unsigned int>() : nullptr, n, b, e, k, tune.sort_cells,
        tune.merge_min, use_heavy ? static_cast<unsigned int>(tune.heavy_candidates) : 0u,
        use_heavy ? heavy.as<unsigned int>() : nullptr,
        use_heavy ? heavy_counts.as<unsigned int>() + c : nullptr, 2 * sms, d_idx, d_d2, d_stats,
        st);
    if (download) {
      const std::size_t r0 = static_cast<std::size_t>(b) * k,
                        nr = static_cast<std::size_t>(e - b) * k;
      GF_CUDA_CHECK(cudaEventRecord(kernel_done[c], st));
      GF_CUDA_CHECK(cudaStreamWaitEvent(copy, kernel_done[c], 0));
      GF_CUDA_CHECK(cudaMemcpyAsync(h_idx.as<std::int32_t>() + r0, d_idx + r0,
                                    nr * sizeof(std::int32_t), cudaMemcpyDeviceToHost, copy));
      if (sq_dists) {
        GF_CUDA_CHECK(cudaMemcpyAsync(h_d2.as<float>() + r0, d_d2 + r0, nr * sizeof(float),
                                      cudaMemcpyDeviceToHost, copy));
      }
      GF_CUDA_CHECK(cudaEventRecord(copy_done[c], copy));
    }
  }
  if (download) {
    const unsigned int* order = h_order.as<unsigned int>();
    const std::int32_t* hi = h_idx.as<std::int32_t>();
    const float* hd = sq_dists ? h_d2.as<float>() : nullptr;
    const std::size_t row_i = static_cast<std::size_t>(k) * sizeof(std::int32_t);
    const std::size_t row_f = static_cast<std::size_t>(k) * sizeof(float);
    for (int c = 0; c < chunks; ++c) {
      const int b = c * per_chunk, e = std::min(n, b + per_chunk);
      if (b >= e) break;
      GF_CUDA_CHECK(cudaEventSynchronize(copy_done[c]));
#pragma omp parallel for schedule(static) if (e - b > 4096)
      for (int s = b; s < e; ++s) {
        const std::size_t dst = static_cast<std::size_t>(order[s]) * k;
        std::memcpy(indices + dst, hi + static_cast<std::size_t>(s) * k, row_i);
        if (hd) std::memcpy(sq_dists + dst, hd + static_cast<std::size_t>(s) * k, row_f);
      }
    }
  }
  if (wait || download || tune.collect_stats) {
    GF_CUDA_CHECK(cudaStreamSynchronize(st));
    GF_CUDA_CHECK(cudaStreamSynchronize(copy));
  }
}

void CudaKnn::Impl::readQueryStats(int n) {
  unsigned long long h[kStatCount];
  GF_CUDA_CHECK(cudaMemcpy(h, small.as<char>() + kSmallStats, sizeof h, cudaMemcpyDeviceToHost));
  const float edge = reinterpret_cast<const float*>(h_small.as<char>() + kSmallFrame)[3];
  stats.candidates_per_query = static_cast<double>(h[kStatCandidates]) / n;
  stats.insertions_per_query = static_cast<double>(h[kStatInsertions]) / n;
  stats.shells_per_query = static_cast<double>(h[kStatShells]) / n;
  stats.levels_per_query = static_cast<double>(h[kStatLevels]) / n;
  stats.mean_query_cycles = static_cast<double>(h[kStatCycles]) / n;
  stats.max_query_cycles = static_cast<double>(h[kStatMaxCycles]);
  auto asFloat = [](unsigned long long v) {
    const unsigned int b = static_cast<unsigned int>(v);
    float f;
    std::memcpy(&f, &b, sizeof f);
    return f;
  };
  std::ostringstream os;
  os << h[kStatHeavy] << " heavy queries (second kernel), " << h[kStatOver100k]
     << " queries > 1e5 cycles, " << h[kStatOver1M] << " > 1e6; slowest: " << h[kStatSlowCand]
     << " candidates, " << h[kStatSlowIns] << " insertions, " << h[kStatSlowShells] << " shells, "
     << h[kStatSlowLevels] << " levels, last level 2^" << h[kStatSlowBits] << " cells/axis (cell "
     << edge / static_cast<float>(1u << h[kStatSlowBits]) << " m), bound "
     << std::sqrt(asFloat(h[kStatSlowLim])) << " m, K-th distance "
     << std::sqrt(asFloat(h[kStatSlowKd])) << " m";
  stats.detail = os.str();
}

void CudaKnn::neighborhoodPca(float* normals, float* eigenvalues, std::uint8_t* valid) {
  Impl& im = *impl_;
  im.requireLists("neighborhoodPca");
  const auto t0 = std::chrono::steady_clock::now();
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  const std::size_t n = im.list_n;
  const std::size_t bytes = n * (6 * sizeof(float) + 1);
  im.grow(im.pca, bytes, "the PCA results");
  im.h_pca.ensure(bytes);
  float* d_normals = im.pca.as<float>();
  float* d_eigen = d_normals + 3 * n;
  std::uint8_t* d_valid = reinterpret_cast<std::uint8_t*>(d_eigen + 3 * n);
  launchPca(im.list_xyz, im.sorted.as<float4>(), im.out_idx.as<std::int32_t>(), static_cast<int>(n),
            im.list_k, d_normals, d_eigen, d_valid, im.stream);
  GF_CUDA_CHECK(
      cudaMemcpyAsync(im.h_pca.ptr, im.pca.ptr, bytes, cudaMemcpyDeviceToHost, im.stream));
  GF_CUDA_CHECK(cudaStreamSynchronize(im.stream));
  const float* h = im.h_pca.as<float>();
  parallelCopy(normals, h, 3 * n * sizeof(float));
  parallelCopy(eigenvalues, h + 3 * n, 3 * n * sizeof(float));
  std::memcpy(valid, h + 6 * n, n);
  im.timings.pca_ms = msSince(t0);
}

void CudaKnn::countFlaggedNeighbors(const std::uint8_t* flags, std::uint16_t* flagged,
                                    std::uint16_t* neighbors) {
  Impl& im = *impl_;
  im.requireLists("countFlaggedNeighbors");
  const auto t0 = std::chrono::steady_clock::now();
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  const std::size_t n = im.list_n;
  im.grow(im.flags, n, "the point flags");
  im.grow(im.counts, 2 * n * sizeof(std::uint16_t), "the neighbour counts");
  im.h_flags.ensure(n);
  im.h_counts.ensure(2 * n * sizeof(std::uint16_t));
  parallelCopy(im.h_flags.ptr, flags, n);
  GF_CUDA_CHECK(
      cudaMemcpyAsync(im.flags.ptr, im.h_flags.ptr, n, cudaMemcpyHostToDevice, im.stream));
  std::uint16_t* d_counts = im.counts.as<std::uint16_t>();
  launchCountFlagged(im.sorted.as<float4>(), im.out_idx.as<std::int32_t>(), static_cast<int>(n),
                     im.list_k, im.flags.as<std::uint8_t>(), d_counts, d_counts + n, im.stream);
  GF_CUDA_CHECK(cudaMemcpyAsync(im.h_counts.ptr, d_counts, 2 * n * sizeof(std::uint16_t),
                                cudaMemcpyDeviceToHost, im.stream));
  GF_CUDA_CHECK(cudaStreamSynchronize(im.stream));
  parallelCopy(flagged, im.h_counts.ptr, n * sizeof(std::uint16_t));
  parallelCopy(neighbors, im.h_counts.as<std::uint16_t>() + n, n * sizeof(std::uint16_t));
  im.timings.count_ms = msSince(t0);
}

std::size_t CudaKnn::listPoints() const { return impl_->list_n; }

void CudaKnnTuningAccess::set(CudaKnn& knn, const CudaKnnTuning& tuning) {
  knn.impl_->tune = tuning;
}
const CudaKnnTuning& CudaKnnTuningAccess::get(const CudaKnn& knn) { return knn.impl_->tune; }
const CudaKnnQueryStats& CudaKnnTuningAccess::stats(const CudaKnn& knn) { return knn.impl_->stats; }

}  // namespace ground_filter
