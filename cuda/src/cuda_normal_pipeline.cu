// CudaNormalPipeline: the whole normal-vector filter on the device.
//
// run(): pack xyz (host, pinned) -> upload -> finite flags, scan, compaction + x/y bounds ->
// [sync: count, bounds] -> column keys (CPU's cellIndex/spreadBits in double) -> stable radix
// sort -> gather -> KNN on the device copy (CudaKnn's grid; it syncs once for its level choice)
// -> PCA + candidates -> vote -> tile keys -> stable sort -> tile heads / voted lists (scans) ->
// RANSAC planes (one block per plane, work queue) -> distance test -> labels download.

#include <cuda_runtime.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>
#include <stdexcept>
#include <string>

#include "cuda_util.cuh"
#include "ground_filter/cuda_normal_pipeline.h"
#include "ground_kernels.cuh"
#include "knn_grid.cuh"
#include "knn_impl.cuh"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {

using namespace cuda_impl;  // NOLINT: private .cu file

namespace {

int bitLength(std::uint64_t v) {
  int b = 0;
  while (v) {
    ++b;
    v >>= 1;
  }
  return b;
}

constexpr int kEvents = 8;

}  // namespace

struct CudaNormalPipeline::Impl {
  explicit Impl(const CudaKnnOptions& o) : knn(o) {}
  CudaKnn knn;
  int sms = 1;
  cudaEvent_t ev[kEvents] = {};
  CudaNormalTimings timings;
  DeviceBuffer in, flags, pos, raw_xyz, raw_src, keys_a, keys_b, vals_a, vals_b, xyz, src, cand,
      voted, vflags, vpos, gflags, gpos, tile_begin, vlist, glist, planes, refine, labels, counters,
      temp;
  PinnedBuffer h_in, h_small, h_labels;
};

CudaNormalPipeline::CudaNormalPipeline(const CudaKnnOptions& options)
    : impl_(std::make_unique<Impl>(options)) {
  Impl& pl = *impl_;
  GF_CUDA_CHECK(cudaSetDevice(options.device));
  GF_CUDA_CHECK(cudaDeviceGetAttribute(&pl.sms, cudaDevAttrMultiProcessorCount, options.device));
  for (auto& e : pl.ev) GF_CUDA_CHECK(cudaEventCreate(&e));
}

CudaNormalPipeline::~CudaNormalPipeline() {
  if (!impl_) return;
  for (auto& e : impl_->ev) {
    if (e) cudaEventDestroy(e);
  }
}

const CudaNormalTimings& CudaNormalPipeline::lastTimings() const { return impl_->timings; }
CudaKnn& CudaNormalPipeline::knn() { return impl_->knn; }
std::size_t CudaNormalPipeline::deviceBytes() const { return impl_->knn.deviceBytes(); }

void CudaNormalPipeline::run(const CloudView& cloud, const CudaNormalParams& prm,
                             std::uint8_t* labels) {
  Impl& pl = *impl_;
  CudaKnn::Impl& im = *pl.knn.impl_;
  const auto t_start = std::chrono::steady_clock::now();
  pl.timings = CudaNormalTimings();
  CudaNormalTimings& tm = pl.timings;
  if (prm.k < 1 || prm.k > CudaKnn::kMaxK) {
    throw std::invalid_argument("CudaNormalPipeline::run: k = " + std::to_string(prm.k) +
                                " is out of range [1, " + std::to_string(CudaKnn::kMaxK) + "]");
  }
  const std::size_t n_in = cloud.size();
  if (n_in >= (1u << 31) - 1) {
    throw std::invalid_argument("CudaNormalPipeline::run: " + std::to_string(n_in) +
                                " points exceed the 2^31 - 1 that int32 indices address");
  }
  if (n_in == 0) return;
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  cudaStream_t st = im.stream;

  // ---- buffers (grow only; the memory limit covers them with the KNN's)
  std::size_t temp_bytes = 0;
  {
    std::size_t sort_bytes = 0, scan_bytes = 0;
    cub::DoubleBuffer<unsigned long long> kb(nullptr, nullptr);
    cub::DoubleBuffer<unsigned int> vb(nullptr, nullptr);
    GF_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, sort_bytes, kb, vb,
                                                  static_cast<int>(n_in), 0, 64, st));
    GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(
        nullptr, scan_bytes, static_cast<unsigned int*>(nullptr),
        static_cast<unsigned int*>(nullptr), static_cast<int>(n_in) + 1, st));
    temp_bytes = std::max(sort_bytes, scan_bytes);
  }
  const std::size_t u32 = sizeof(unsigned int), u64 = sizeof(unsigned long long);
  im.grow(pl.in, 3 * n_in * sizeof(float), "the input points");
  im.grow(pl.flags, (n_in + 1) * u32, "the finite flags");
  im.grow(pl.pos, (n_in + 1) * u32, "the compaction scan");
  im.grow(pl.raw_xyz, 3 * n_in * sizeof(float), "the compacted points");
  im.grow(pl.raw_src, n_in * u32, "the compacted points");
  im.grow(pl.keys_a, n_in * u64, "the sort keys");
  im.grow(pl.keys_b, n_in * u64, "the sort keys");
  im.grow(pl.vals_a, n_in * u32, "the sort order");
  im.grow(pl.vals_b, n_in * u32, "the sort order");
  im.grow(pl.xyz, 3 * n_in * sizeof(float), "the ordered points");
  im.grow(pl.src, n_in * u32, "the ordered points");
  im.grow(pl.cand, n_in, "the candidates");
  im.grow(pl.voted, n_in, "the votes");
  im.grow(pl.vflags, (n_in + 1) * u32, "the tile lists");
  im.grow(pl.vpos, (n_in + 1) * u32, "the tile lists");
  im.grow(pl.gflags, (n_in + 1) * u32, "the tile lists");
  im.grow(pl.gpos, (n_in + 1) * u32, "the tile lists");
  im.grow(pl.tile_begin, (n_in + 1) * u32, "the tile lists");
  im.grow(pl.vlist, n_in * u32, "the tile lists");
  im.grow(pl.glist, n_in * u32, "the tile lists");
  im.grow(pl.labels, n_in, "the labels");
  im.grow(pl.counters, 64, "the counters");
  im.grow(pl.refine, refinePartialBytes(), "the plane sums");
  im.grow(pl.temp, temp_bytes, "the sort/scan scratch");
  pl.h_in.ensure(3 * n_in * sizeof(float));
  pl.h_small.ensure(64);
  pl.h_labels.ensure(n_in);

  // ---- pack (host) and upload
  auto t0 = std::chrono::steady_clock::now();
  float* h_in = pl.h_in.as<float>();
  const std::int64_t nn = static_cast<std::int64_t>(n_in);
  // One thread per 32 k points, up to all: a KITTI/OS-128 frame packs in 0.3/0.6 ms on one
  // thread, and waking a few threads costs far less.
  const int pack_threads = static_cast<int>(
      std::max<std::int64_t>(1, std::min<std::int64_t>(omp_get_max_threads(), nn >> 15)));
#pragma omp parallel for schedule(static) num_threads(pack_threads) if (pack_threads > 1)
  for (std::int64_t i = 0; i < nn; ++i) {
    h_in[3 * i] = cloud.x(static_cast<std::size_t>(i));
    h_in[3 * i + 1] = cloud.y(static_cast<std::size_t>(i));
    h_in[3 * i + 2] = cloud.z(static_cast<std::size_t>(i));
  }
  tm.pack_ms = msSince(t0);
  GF_CUDA_CHECK(cudaEventRecord(pl.ev[0], st));
  GF_CUDA_CHECK(
      cudaMemcpyAsync(pl.in.ptr, h_in, 3 * n_in * sizeof(float), cudaMemcpyHostToDevice, st));
  GF_CUDA_CHECK(cudaEventRecord(pl.ev[1], st));

  // ---- compaction of the finite points, x/y bounds
  const int n_all = static_cast<int>(n_in);
  unsigned int* d_flags = pl.flags.as<unsigned int>();
  unsigned int* d_pos = pl.pos.as<unsigned int>();
  unsigned int* d_counters = pl.counters.as<unsigned int>();  // [0..3] bounds, [4..] counters
  int* d_bounds = reinterpret_cast<int*>(d_counters);
  launchFiniteFlags(pl.in.as<float>(), n_all, d_flags, st);
  std::size_t tb = pl.temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(pl.temp.ptr, tb, d_flags, d_pos, n_all + 1, st));
  launchCompact(pl.in.as<float>(), d_flags, d_pos, n_all, pl.raw_xyz.as<float>(),
                pl.raw_src.as<unsigned int>(), d_bounds, st);
  GF_CUDA_CHECK(cudaMemsetAsync(d_counters + 4, 0, 32, st));
  char* h_small = pl.h_small.as<char>();
  GF_CUDA_CHECK(cudaMemcpyAsync(h_small, d_bounds, 16, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaMemcpyAsync(h_small + 16, d_pos + n_in, u32, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  int hb[4];
  std::memcpy(hb, h_small, 16);
  unsigned int n_valid = 0;
  std::memcpy(&n_valid, h_small + 16, u32);
  tm.valid_points = n_valid;
  if (n_valid == 0) {
    std::memset(labels, 0, n_in);
    tm.total_ms = msSince(t_start);
    return;
  }
  const int n = static_cast<int>(n_valid);
  // CPU: min/max of the finite points' x/y as double, grid cell coarsened for very wide clouds.
  const double min_x = orderedToFloat(hb[0]), min_y = orderedToFloat(hb[1]);
  const double max_x = orderedToFloat(hb[2]), max_y = orderedToFloat(hb[3]);
  const double extent = std::max(max_x - min_x, max_y - min_y);
  const double cell = std::max(prm.cell_size, extent / 4.0e9);
  const double inv_cell = 1.0 / cell;
  const int col_bits = bitLength(
      std::max(normal::cellIndex(max_x, min_x, inv_cell), normal::cellIndex(max_y, min_y, inv_cell)));
  launchColumnKeys(pl.raw_xyz.as<float>(), n, min_x, min_y, inv_cell,
                   pl.keys_a.as<unsigned long long>(), pl.vals_a.as<unsigned int>(), st);
  {
    cub::DoubleBuffer<unsigned long long> kb(pl.keys_a.as<unsigned long long>(),
                                             pl.keys_b.as<unsigned long long>());
    cub::DoubleBuffer<unsigned int> vb(pl.vals_a.as<unsigned int>(), pl.vals_b.as<unsigned int>());
    tb = pl.temp.bytes;
    GF_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(pl.temp.ptr, tb, kb, vb, n, 0,
                                                  std::max(1, 2 * col_bits), st));
    launchGatherColumns(pl.raw_xyz.as<float>(), pl.raw_src.as<unsigned int>(), vb.Current(), n,
                        pl.xyz.as<float>(), pl.src.as<unsigned int>(), st);
  }
  GF_CUDA_CHECK(cudaEventRecord(pl.ev[2], st));

  // ---- K nearest neighbours of the ordered points (lists stay on the device)
  im.timings = CudaKnnTimings();
  im.searchOnDevice(pl.xyz.as<float>(), n, prm.k, nullptr, nullptr);
  GF_CUDA_CHECK(cudaEventRecord(pl.ev[3], st));

  // ---- PCA + candidates, vote
  GroundParamsDev gp;
  gp.k = prm.k;
  gp.iterations = prm.ransac_iterations;
  gp.seed = normal::ransacBaseSeed(static_cast<std::uint32_t>(prm.ransac_seed));
  gp.min_abs_nz = prm.min_abs_nz;
  gp.min_planarity = prm.min_planarity;
  gp.plane_distance = prm.plane_distance;
  gp.std_multiplier = prm.std_multiplier;
  gp.floor_share = prm.floor_share;
  gp.floor_max_shift = prm.floor_max_shift;
  gp.bayes_vote = prm.bayes_vote;
  gp.std_filter = prm.std_filter;
  gp.plane_all_points = prm.plane_all_points;
  gp.local_planes = prm.local_planes;
  unsigned int* d_cand_count = d_counters + 4;
  unsigned int* d_ground_count = d_counters + 5;
  unsigned int* d_work_planes = d_counters + 6;
  unsigned int* d_work_classify = d_counters + 7;
  unsigned int* d_need_global = d_counters + 8;
  const float4* d_pts = im.sorted.as<float4>();
  const std::int32_t* d_rows = im.out_idx.as<std::int32_t>();
  std::uint8_t* d_cand = pl.cand.as<std::uint8_t>();
  std::uint8_t* d_voted = pl.voted.as<std::uint8_t>();
  launchPcaCandidates(pl.xyz.as<float>(), d_pts, d_rows, n, gp, d_cand, d_cand_count, st);
  GF_CUDA_CHECK(cudaEventRecord(pl.ev[4], st));
  launchVote(d_pts, d_rows, n, gp, d_cand, d_cand_count, d_voted, st);
  GF_CUDA_CHECK(cudaEventRecord(pl.ev[5], st));

  // ---- tiles, planes, distance test
  const double tile = std::max(prm.tile_size, extent / 4.0e9);
  const double inv_tile = 1.0 / tile;
  const std::uint64_t tx_max = normal::cellIndex(max_x, min_x, inv_tile);
  const std::uint64_t ty_max = normal::cellIndex(max_y, min_y, inv_tile);
  const int tile_bits = prm.local_planes ? 32 + bitLength(tx_max) : 1;
  std::uint64_t tiles_max = 1;
  if (prm.local_planes) {  // occupied tiles, at most: min(points, tiles of the bounding box)
    tiles_max = (tx_max + 1) > static_cast<std::uint64_t>(n) / (ty_max + 1)
                    ? static_cast<std::uint64_t>(n)
                    : std::min<std::uint64_t>(n, (tx_max + 1) * (ty_max + 1));
  }
  im.grow(pl.planes, (tiles_max + 1) * sizeof(PlaneDev), "the planes");
  const float* d_xyz = pl.xyz.as<float>();
  launchTileKeys(d_xyz, n, prm.local_planes, min_x, min_y, inv_tile,
                 pl.keys_a.as<unsigned long long>(), pl.vals_a.as<unsigned int>(), st);
  cub::DoubleBuffer<unsigned long long> kb(pl.keys_a.as<unsigned long long>(),
                                           pl.keys_b.as<unsigned long long>());
  cub::DoubleBuffer<unsigned int> vb(pl.vals_a.as<unsigned int>(), pl.vals_b.as<unsigned int>());
  tb = pl.temp.bytes;
  GF_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(pl.temp.ptr, tb, kb, vb, n, 0, tile_bits, st));
  const unsigned long long* d_tkeys = kb.Current();
  const unsigned int* d_order = vb.Current();
  unsigned int* d_heads = d_flags;  // reused
  unsigned int* d_tile_idx = d_pos;
  launchTileFlags(d_tkeys, d_order, d_voted, n, d_heads, pl.vflags.as<unsigned int>(),
                  pl.gflags.as<unsigned int>(), st);
  tb = pl.temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(pl.temp.ptr, tb, d_heads, d_tile_idx, n + 1, st));
  tb = pl.temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(pl.temp.ptr, tb, pl.vflags.as<unsigned int>(),
                                              pl.vpos.as<unsigned int>(), n + 1, st));
  tb = pl.temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(pl.temp.ptr, tb, pl.gflags.as<unsigned int>(),
                                              pl.gpos.as<unsigned int>(), n + 1, st));
  launchTileLists(d_heads, d_tile_idx, d_order, d_voted, pl.vpos.as<unsigned int>(),
                  pl.gpos.as<unsigned int>(), n, pl.tile_begin.as<unsigned int>(),
                  pl.vlist.as<unsigned int>(), pl.glist.as<unsigned int>(), st);
  const unsigned int* d_ntiles = d_tile_idx + n;
  const unsigned int* d_gcount = pl.gpos.as<unsigned int>() + n;
  PlaneDev* d_planes = pl.planes.as<PlaneDev>();
  const int plane_blocks = static_cast<int>(std::min<std::uint64_t>(tiles_max + 1, 8ull * pl.sms));
  launchPlanes(d_xyz, d_tkeys, pl.tile_begin.as<unsigned int>(), d_ntiles,
               pl.vpos.as<unsigned int>(), pl.vlist.as<unsigned int>(), pl.glist.as<unsigned int>(),
               d_gcount, gp, d_planes, d_work_planes, d_need_global, pl.refine.as<double>(),
               tiles_max, plane_blocks, st);
  std::uint8_t* d_labels = pl.labels.as<std::uint8_t>();
  GF_CUDA_CHECK(cudaMemsetAsync(d_labels, 0, n_in, st));
  const int classify_blocks = static_cast<int>(std::min<std::uint64_t>(tiles_max, 8ull * pl.sms));
  launchClassify(d_xyz, pl.src.as<unsigned int>(), d_order, d_voted,
                 pl.tile_begin.as<unsigned int>(), d_ntiles, pl.vpos.as<unsigned int>(),
                 pl.vlist.as<unsigned int>(), gp, d_planes, d_labels, d_ground_count,
                 d_work_classify, classify_blocks, st);
  GF_CUDA_CHECK(cudaEventRecord(pl.ev[6], st));

  // ---- labels (and counts) down
  GF_CUDA_CHECK(cudaMemcpyAsync(pl.h_labels.ptr, d_labels, n_in, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaMemcpyAsync(h_small + 32, d_ground_count, u32, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaMemcpyAsync(h_small + 36, d_ntiles, u32, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaEventRecord(pl.ev[7], st));
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  parallelCopy(labels, pl.h_labels.ptr, n_in);
  unsigned int ground = 0, ntiles = 0;
  std::memcpy(&ground, h_small + 32, u32);
  std::memcpy(&ntiles, h_small + 36, u32);
  tm.ground_points = ground;
  tm.tiles = ntiles;
  auto span = [&](int a, int b) {
    float ms = 0.f;
    GF_CUDA_CHECK(cudaEventElapsedTime(&ms, pl.ev[a], pl.ev[b]));
    return static_cast<double>(ms);
  };
  tm.upload_ms = span(0, 1);
  tm.sort_ms = span(1, 2);
  tm.knn_ms = span(2, 3);
  tm.pca_ms = span(3, 4);
  tm.vote_ms = span(4, 5);
  tm.plane_ms = span(5, 6);
  tm.download_ms = span(6, 7);
  tm.total_ms = msSince(t_start);
}

}  // namespace ground_filter
