// CudaNormalPipeline: the whole normal-vector filter on the device.
//
// run(): pack xyz (host, pinned; the finite points' count and x/y bounds on the way, so no sync
// waits for them) -> upload -> finite flags, scan, compaction -> column keys (CPU's
// cellIndex/spreadBits in double) -> stable radix sort -> gather -> [sample_stride > 1: every
// stride-th point, a dense column capped; sync: m]
// -> KNN on the device copy
// (CudaKnn's grid; it syncs once for its level choice)
// -> PCA + candidates -> vote -> tile keys -> stable sort -> tile heads / voted lists (scans) ->
// RANSAC planes (one block per plane, work queue) -> distance test -> labels download.

#include <cuda_runtime.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>
#include <stdexcept>
#include <string>

#include "cuda_util.cuh"
#include "ground_classify.cuh"
#include "ground_columns.cuh"
#include "ground_filter/cuda_normal_pipeline.h"
#include "ground_local.cuh"
#include "ground_planes.cuh"
#include "ground_tiles.cuh"
#include "ground_vote.cuh"
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

/// The finite points of a packed range: count and x/y bounds (what the device's finite flags and
/// compaction keep; min / max are exact, so the split into ranges does not matter).
struct PackStats {
  unsigned int valid = 0;
  float min_x = INFINITY, min_y = INFINITY, max_x = -INFINITY, max_y = -INFINITY;
  void merge(const PackStats& o) {
    valid += o.valid;
    min_x = std::min(min_x, o.min_x);
    min_y = std::min(min_y, o.min_y);
    max_x = std::max(max_x, o.max_x);
    max_y = std::max(max_y, o.max_y);
  }
};

/// Packs points [b, e) of the view as x y z triplets into hp (3 floats a point) and counts the
/// finite ones (x, y and z finite, as finiteFlagsKernel) and their x/y bounds. Where x y z are
/// adjacent, one 16-byte load and store a point: the load's 4th float is the record's next field
/// or the next record's x (so not for the view's last record when the 12 bytes end it), and the
/// store's is overwritten by the next point (not stored for the range's last one).
void packRange(const CloudView& cloud, std::int64_t b, std::int64_t e, float* hp, PackStats* s) {
  std::int64_t i = b;
#if defined(__SSE2__)
  if (cloud.xyzAdjacent()) {
    const std::int64_t n = static_cast<std::int64_t>(cloud.size());
    const std::int64_t simd_end = cloud.xyzFollowedByFloat() ? e : std::min(e, n - 1);
    const std::uint8_t* rec = cloud.data() + cloud.xOffset();
    const std::size_t stride = cloud.stride();
    __m128 lo = _mm_set1_ps(INFINITY), hi = _mm_set1_ps(-INFINITY);
    const __m128 zero = _mm_setzero_ps();
    unsigned int valid = 0;
    for (; i < simd_end; ++i) {
      const __m128 p =
          _mm_loadu_ps(reinterpret_cast<const float*>(rec + static_cast<std::size_t>(i) * stride));
      if (i + 1 < e) {
        _mm_storeu_ps(hp + 3 * i, p);
      } else {
        alignas(16) float v[4];
        _mm_store_ps(v, p);
        std::memcpy(hp + 3 * i, v, 3 * sizeof(float));
      }
      // p - p is 0 in a finite lane, NaN in an infinite or NaN one.
      if ((_mm_movemask_ps(_mm_cmpeq_ps(_mm_sub_ps(p, p), zero)) & 7) == 7) {
        ++valid;
        lo = _mm_min_ps(lo, p);
        hi = _mm_max_ps(hi, p);
      }
    }
    alignas(16) float l[4], h[4];
    _mm_store_ps(l, lo);
    _mm_store_ps(h, hi);
    s->merge(PackStats{valid, l[0], l[1], h[0], h[1]});
  }
#endif
  for (; i < e; ++i) {
    float* o = hp + 3 * i;
    if (cloud.get(static_cast<std::size_t>(i), o, o + 1, o + 2)) {
      s->merge(PackStats{1, o[0], o[1], o[0], o[1]});
    }
  }
}

/// The finite points' x/y bounds (as double, like the CPU's).
struct XyBounds {
  double min_x, min_y, max_x, max_y;
};

}  // namespace

struct CudaNormalPipeline::Impl {
  explicit Impl(const CudaKnnOptions& o) : knn(o) {}
  CudaKnn knn;
  int sms = 1;
  cudaEvent_t ev[kEvents] = {};
  CudaNormalTimings timings;
  DeviceBuffer in, flags, pos, raw_xyz, raw_src, keys_a, keys_b, vals_a, vals_b, xyz, src, cand,
      voted, sampled_xyz, sampled_voted, vflags, vpos, gflags, gpos, tile_begin, vlist, glist,
      planes, donor, refine, labels, counters, temp, sidx, column_low;
  PinnedBuffer h_in, h_small, h_labels;
  const unsigned long long* col_keys = nullptr;  // sorted column keys (orderColumns), n entries

  // The sections of run(), in their order; all on the KNN's stream `im.stream`.
  // `counters` (device, 64 B): the counters below, zeroed at the start of each pass (run()).
  unsigned int* candCount() { return counters.as<unsigned int>(); }
  unsigned int* groundCount() { return counters.as<unsigned int>() + 1; }
  unsigned int* workPlanes() { return counters.as<unsigned int>() + 2; }
  unsigned int* workClassify() { return counters.as<unsigned int>() + 3; }
  unsigned int* needGlobal() { return counters.as<unsigned int>() + 4; }
  unsigned int* sensorCounts() { return counters.as<unsigned int>() + 5; }  // 5, 6

  /// Grows every buffer but the planes (grow only; the memory limit covers them with the KNN's).
  void growBuffers(CudaKnn::Impl& im, std::size_t n_in);
  /// Packs the view's xyz into pinned memory and uploads it (events 0, 1); returns the count of
  /// the finite points and their x/y bounds, which the device's compaction keeps.
  unsigned int packAndUpload(CudaKnn::Impl& im, const CloudView& cloud, std::size_t n_in,
                             XyBounds* bounds);
  /// Compacts the finite points (raw_xyz, raw_src).
  void compactFinite(CudaKnn::Impl& im, std::size_t n_in);
  /// Grid-column order of the n compacted points: xyz, src (event 2).
  void orderColumns(CudaKnn::Impl& im, int n, const XyBounds& bb, double cell_size,
                    bool all_finite);
  /// The sampled points (CPU: SampleStage::gather): sidx (m + 1 entries), sampled_xyz, and the
  /// per-point flags and their scan in vflags / vpos (free until the tiles); downloads m.
  int sample(CudaKnn::Impl& im, int n, int stride, int cap);
  /// PCA + candidates, vote of the m searched points `q` into `out` (events 4, 5).
  void candidatesAndVote(CudaKnn::Impl& im, const float* q, int m, const GroundParamsDev& gp,
                         std::uint8_t* out);
  /// Tiles, RANSAC planes, distance test into `labels` (device, n_in entries; event 6).
  void planesAndLabels(CudaKnn::Impl& im, int n, std::size_t n_in, const XyBounds& bb,
                       const CudaNormalParams& prm, const GroundParamsDev& gp);
  /// Local ground plane on the labels (local_ground_min > 0; before event 6).
  void localGround(CudaKnn::Impl& im, int n, int m, const unsigned int* d_sidx,
                   const GroundParamsDev& gp);
  /// Labels and counts down into `out` (event 7), stage times from the events.
  /// Returns the candidates among the sampled points (candCount()).
  unsigned int downloadLabels(CudaKnn::Impl& im, std::size_t n_in, std::uint8_t* out);
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

void CudaNormalPipeline::lastColumnOrder(std::vector<std::uint32_t>* source) {
  Impl& pl = *impl_;
  CudaKnn::Impl& im = *pl.knn.impl_;
  const std::size_t n = pl.timings.valid_points;
  source->resize(n);
  if (n == 0) return;
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  // `src` holds the ordered points' input indices until the next run().
  GF_CUDA_CHECK(cudaMemcpyAsync(source->data(), pl.src.ptr, n * sizeof(std::uint32_t),
                                cudaMemcpyDeviceToHost, im.stream));
  GF_CUDA_CHECK(cudaStreamSynchronize(im.stream));
}

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
  if (prm.sample_stride < 1) {  // the range: NormalGroundFilterParams::validate()
    throw std::invalid_argument("CudaNormalPipeline::run: sample_stride = " +
                                std::to_string(prm.sample_stride) + " is below 1");
  }
  const std::size_t n_in = cloud.size();
  if (n_in >= (1u << 31) - 1) {
    throw std::invalid_argument("CudaNormalPipeline::run: " + std::to_string(n_in) +
                                " points exceed the 2^31 - 1 that int32 indices address");
  }
  if (n_in == 0) return;
  GF_CUDA_CHECK(cudaSetDevice(im.opt.device));
  pl.growBuffers(im, n_in);
  XyBounds bb;
  const unsigned int n_valid = pl.packAndUpload(im, cloud, n_in, &bb);
  tm.valid_points = n_valid;
  if (n_valid == 0) {
    GF_CUDA_CHECK(cudaStreamSynchronize(im.stream));  // the upload reads the pinned input
    std::memset(labels, 0, n_in);
    tm.total_ms = msSince(t_start);
    return;
  }
  // Every point finite (the packing counted them; most drivers' clouds hold no NaN): the input
  // is its own compaction, and the compaction's four launches are left out.
  const bool all_finite = n_valid == n_in;
  if (!all_finite) pl.compactFinite(im, n_in);
  const int n = static_cast<int>(n_valid);
  pl.orderColumns(im, n, bb, prm.cell_size, all_finite);

  // ---- the sampled points (CPU: SampleStage), their K nearest neighbours (lists stay on the
  //      device), PCA + candidates and vote; the others: OR of the samples before and after
  //      The whole scan again with a wider stride when too few sampled points were candidates
  //      (the CPU filter's rule, normal::sparseLinesStride(); its count comes down with the
  //      labels, so a scan that keeps its stride pays no extra sync).
  int stride = prm.sample_stride;
  for (;;) {
    GF_CUDA_CHECK(cudaMemsetAsync(pl.counters.ptr, 0, 32, im.stream));  // this pass's counters
    int m = n;
    const float* q = pl.xyz.as<float>();
    const unsigned int* d_sidx = nullptr;  // null: every point sampled
    if (stride > 1) {
      m = pl.sample(im, n, stride, normal::columnSampleCap(prm.k));
      q = pl.sampled_xyz.as<float>();
      d_sidx = pl.sidx.as<unsigned int>();
    }
    im.timings = CudaKnnTimings();
    im.stats = CudaKnnQueryStats();
    // No wait for the queries: the host queues the stages after them meanwhile (the GPU ran
    // them with a launch gap before each: docs/gpu.md, "The host side, traced").
    im.searchOnDevice(q, m, prm.k, nullptr, nullptr, /*wait=*/false);
    GF_CUDA_CHECK(cudaEventRecord(pl.ev[3], im.stream));

    const GroundParamsDev& gp = prm;
    std::uint8_t* d_voted = pl.voted.as<std::uint8_t>();
    pl.candidatesAndVote(im, q, m, gp, stride > 1 ? pl.sampled_voted.as<std::uint8_t>() : d_voted);
    if (stride > 1) {
      launchSpreadVotes(pl.sampled_voted.as<std::uint8_t>(), pl.vflags.as<unsigned int>(),
                        pl.vpos.as<unsigned int>(), m, n, d_voted, im.stream);
    }
    pl.planesAndLabels(im, n, n_in, bb, prm, gp);
    if (gp.local_ground_min > 0) pl.localGround(im, n, m, d_sidx, gp);
    GF_CUDA_CHECK(cudaEventRecord(pl.ev[6], im.stream));
    const unsigned int candidates = pl.downloadLabels(im, n_in, labels);
    const int wider = normal::sparseLinesStride(candidates, static_cast<std::size_t>(m),
                                                prm.min_candidate_share, stride);
    if (wider == 0) break;
    stride = wider;
  }
  tm.sample_stride = stride;
  tm.total_ms = msSince(t_start);
}

// ---- buffers (grow only; the memory limit covers them with the KNN's)
void CudaNormalPipeline::Impl::growBuffers(CudaKnn::Impl& im, std::size_t n_in) {
  cudaStream_t st = im.stream;
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
  im.grow(in, 3 * n_in * sizeof(float), "the input points");
  im.grow(flags, (n_in + 1) * u32, "the finite flags");
  im.grow(pos, (n_in + 1) * u32, "the compaction scan");
  im.grow(raw_xyz, 3 * n_in * sizeof(float), "the compacted points");
  im.grow(raw_src, n_in * u32, "the compacted points");
  im.grow(keys_a, n_in * u64, "the sort keys");
  im.grow(keys_b, n_in * u64, "the sort keys");
  im.grow(vals_a, n_in * u32, "the sort order");
  im.grow(vals_b, n_in * u32, "the sort order");
  im.grow(xyz, 3 * n_in * sizeof(float), "the ordered points");
  im.grow(src, n_in * u32, "the ordered points");
  im.grow(cand, n_in, "the candidates");
  im.grow(voted, n_in, "the votes");
  im.grow(sampled_xyz, 3 * n_in * sizeof(float), "the sampled points");
  im.grow(sampled_voted, n_in, "the votes");
  im.grow(sidx, (n_in + 1) * u32, "the sampled points");
  im.grow(vflags, (n_in + 1) * u32, "the tile lists");
  im.grow(vpos, (n_in + 1) * u32, "the tile lists");
  im.grow(gflags, (n_in + 1) * u32, "the tile lists");
  im.grow(gpos, (n_in + 1) * u32, "the tile lists");
  im.grow(tile_begin, (n_in + 1) * u32, "the tile lists");
  im.grow(vlist, n_in * u32, "the tile lists");
  im.grow(glist, n_in * u32, "the tile lists");
  im.grow(labels, n_in, "the labels");
  im.grow(counters, 64, "the counters");
  im.grow(refine, refinePartialBytes(), "the plane sums");
  im.grow(temp, temp_bytes, "the sort/scan scratch");
  h_in.ensure(3 * n_in * sizeof(float));
  h_small.ensure(64);
  h_labels.ensure(n_in);
}

// ---- pack (host) and upload
unsigned int CudaNormalPipeline::Impl::packAndUpload(CudaKnn::Impl& im, const CloudView& cloud,
                                                     std::size_t n_in, XyBounds* bounds) {
  cudaStream_t st = im.stream;
  const auto t0 = std::chrono::steady_clock::now();
  float* hp = h_in.as<float>();
  const std::int64_t nn = static_cast<std::int64_t>(n_in);
  // One thread per 32 k points, up to all: a KITTI/OS-128 frame packs in 0.3/0.6 ms on one
  // thread, and waking a few threads costs far less; waking more costs more than it saves (one
  // per 16 k / 8 k points: 0.30-0.48 / 0.53-0.72 ms a KITTI frame against 0.11-0.14, H200 host).
  const int pack_threads = static_cast<int>(
      std::max<std::int64_t>(1, std::min<std::int64_t>(omp_get_max_threads(), nn >> 15)));
  PackStats all;
#pragma omp parallel num_threads(pack_threads) if (pack_threads > 1)
  {
    const std::int64_t nt = omp_get_num_threads(), t = omp_get_thread_num();
    PackStats mine;
    packRange(cloud, nn * t / nt, nn * (t + 1) / nt, hp, &mine);
#pragma omp critical
    all.merge(mine);
  }
  timings.pack_ms = msSince(t0);
  GF_CUDA_CHECK(cudaEventRecord(ev[0], st));
  GF_CUDA_CHECK(cudaMemcpyAsync(in.ptr, hp, 3 * n_in * sizeof(float), cudaMemcpyHostToDevice, st));
  GF_CUDA_CHECK(cudaEventRecord(ev[1], st));
  *bounds = XyBounds{all.min_x, all.min_y, all.max_x, all.max_y};
  return all.valid;
}

// ---- compaction of the finite points
void CudaNormalPipeline::Impl::compactFinite(CudaKnn::Impl& im, std::size_t n_in) {
  cudaStream_t st = im.stream;
  const int n_all = static_cast<int>(n_in);
  unsigned int* d_flags = flags.as<unsigned int>();
  unsigned int* d_pos = pos.as<unsigned int>();
  launchFiniteFlags(in.as<float>(), n_all, d_flags, st);
  std::size_t tb = temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.ptr, tb, d_flags, d_pos, n_all + 1, st));
  launchCompact(in.as<float>(), d_flags, d_pos, n_all, raw_xyz.as<float>(),
                raw_src.as<unsigned int>(), st);
}

// ---- grid-column order (CPU: cellIndex + spreadBits), grid cell coarsened for very wide clouds
void CudaNormalPipeline::Impl::orderColumns(CudaKnn::Impl& im, int n, const XyBounds& bb,
                                            double cell_size, bool all_finite) {
  cudaStream_t st = im.stream;
  // all_finite: the points are the input as uploaded, each its own source index.
  const float* d_raw = all_finite ? in.as<float>() : raw_xyz.as<float>();
  const unsigned int* d_raw_src = all_finite ? nullptr : raw_src.as<unsigned int>();
  const double extent = std::max(bb.max_x - bb.min_x, bb.max_y - bb.min_y);
  const double cell = std::max(cell_size, extent / 4.0e9);
  const double inv_cell = 1.0 / cell;
  const int col_bits = bitLength(std::max(normal::cellIndex(bb.max_x, bb.min_x, inv_cell),
                                          normal::cellIndex(bb.max_y, bb.min_y, inv_cell)));
  launchColumnKeys(d_raw, n, bb.min_x, bb.min_y, inv_cell, keys_a.as<unsigned long long>(),
                   vals_a.as<unsigned int>(), st);
  cub::DoubleBuffer<unsigned long long> kb(keys_a.as<unsigned long long>(),
                                           keys_b.as<unsigned long long>());
  cub::DoubleBuffer<unsigned int> vb(vals_a.as<unsigned int>(), vals_b.as<unsigned int>());
  std::size_t tb = temp.bytes;
  GF_CUDA_CHECK(
      cub::DeviceRadixSort::SortPairs(temp.ptr, tb, kb, vb, n, 0, std::max(1, 2 * col_bits), st));
  launchGatherColumns(d_raw, d_raw_src, vb.Current(), n, xyz.as<float>(), src.as<unsigned int>(),
                      st);
  col_keys = kb.Current();
  GF_CUDA_CHECK(cudaEventRecord(ev[2], st));
}

// ---- the sampled points; the one sync before the KNN: m sizes its launch
int CudaNormalPipeline::Impl::sample(CudaKnn::Impl& im, int n, int stride, int cap) {
  cudaStream_t st = im.stream;
  unsigned int* d_flags = vflags.as<unsigned int>();
  unsigned int* d_pos = vpos.as<unsigned int>();
  unsigned int* d_sidx = sidx.as<unsigned int>();
  launchSampleFlags(col_keys, n, stride, cap, d_flags, st);
  std::size_t tb = temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.ptr, tb, d_flags, d_pos, n + 1, st));
  launchSampleIndex(d_flags, d_pos, n, d_sidx, st);
  char* hs = h_small.as<char>();
  GF_CUDA_CHECK(
      cudaMemcpyAsync(hs + 40, d_pos + n, sizeof(unsigned int), cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  unsigned int m = 0;
  std::memcpy(&m, hs + 40, sizeof m);
  launchSampleGather(xyz.as<float>(), d_sidx, static_cast<int>(m), sampled_xyz.as<float>(), st);
  return static_cast<int>(m);
}

// ---- PCA + candidates, vote
void CudaNormalPipeline::Impl::candidatesAndVote(CudaKnn::Impl& im, const float* q, int m,
                                                 const GroundParamsDev& gp, std::uint8_t* out) {
  cudaStream_t st = im.stream;
  const float4* d_pts = im.sorted.as<float4>();
  const std::int32_t* d_rows = im.out_idx.as<std::int32_t>();
  std::uint8_t* d_cand = cand.as<std::uint8_t>();
  launchPcaCandidates(q, d_pts, d_rows, m, gp, d_cand, candCount(), st);
  GF_CUDA_CHECK(cudaEventRecord(ev[4], st));
  launchVote(d_pts, d_rows, m, gp, d_cand, candCount(), out, st);
  GF_CUDA_CHECK(cudaEventRecord(ev[5], st));
}

// ---- tiles, planes, distance test
void CudaNormalPipeline::Impl::planesAndLabels(CudaKnn::Impl& im, int n, std::size_t n_in,
                                               const XyBounds& bb, const CudaNormalParams& prm,
                                               const GroundParamsDev& gp) {
  cudaStream_t st = im.stream;
  const double extent = std::max(bb.max_x - bb.min_x, bb.max_y - bb.min_y);
  const double tile = std::max(prm.tile_size, extent / 4.0e9);
  const double inv_tile = 1.0 / tile;
  const std::uint64_t tx_max = normal::cellIndex(bb.max_x, bb.min_x, inv_tile);
  const std::uint64_t ty_max = normal::cellIndex(bb.max_y, bb.min_y, inv_tile);
  // Tile keys tx << ybits | ty: the order of the CPU's (tx << 32) | ty (plane.cpp; the RANSAC
  // seeds are drawn from it) in the fewest radix passes (KITTI: 12 bits, 2 passes instead of 5).
  const int ybits = prm.local_planes ? bitLength(ty_max) : 0;
  const int tile_bits = prm.local_planes ? std::max(1, bitLength(tx_max) + ybits) : 1;
  std::uint64_t tiles_max = 1;
  if (prm.local_planes) {  // occupied tiles, at most: min(points, tiles of the bounding box)
    tiles_max = (tx_max + 1) > static_cast<std::uint64_t>(n) / (ty_max + 1)
                    ? static_cast<std::uint64_t>(n)
                    : std::min<std::uint64_t>(n, (tx_max + 1) * (ty_max + 1));
  }
  im.grow(planes, (tiles_max + 1) * sizeof(PlaneDev), "the planes");
  im.grow(donor, tiles_max * sizeof(int), "the raised-tile test");
  const float* d_xyz = xyz.as<float>();
  std::uint8_t* d_voted = voted.as<std::uint8_t>();
  // Without a sensor to judge the planes by, no voted point over another (CPU: PlaneStage::run).
  const normal::OverheadGrid og = normal::overheadGrid(bb.min_x, bb.min_y, bb.max_x, bb.max_y);
  im.grow(column_low, static_cast<std::size_t>(og.nx) * og.ny * sizeof(int), "the overhead test");
  launchUnvoteOverhead(d_xyz, d_voted, n, og, gp, sensorCounts(), column_low.as<int>(), st);
  launchTileKeys(d_xyz, n, prm.local_planes, bb.min_x, bb.min_y, inv_tile, ybits,
                 keys_a.as<unsigned long long>(), vals_a.as<unsigned int>(), st);
  cub::DoubleBuffer<unsigned long long> kb(keys_a.as<unsigned long long>(),
                                           keys_b.as<unsigned long long>());
  cub::DoubleBuffer<unsigned int> vb(vals_a.as<unsigned int>(), vals_b.as<unsigned int>());
  std::size_t tb = temp.bytes;
  GF_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(temp.ptr, tb, kb, vb, n, 0, tile_bits, st));
  const unsigned long long* d_tkeys = kb.Current();
  const unsigned int* d_order = vb.Current();
  unsigned int* d_heads = flags.as<unsigned int>();  // reused
  unsigned int* d_tile_idx = pos.as<unsigned int>();
  launchTileFlags(d_tkeys, d_order, d_voted, n, d_heads, vflags.as<unsigned int>(),
                  gflags.as<unsigned int>(), st);
  tb = temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.ptr, tb, d_heads, d_tile_idx, n + 1, st));
  tb = temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.ptr, tb, vflags.as<unsigned int>(),
                                              vpos.as<unsigned int>(), n + 1, st));
  tb = temp.bytes;
  GF_CUDA_CHECK(cub::DeviceScan::ExclusiveSum(temp.ptr, tb, gflags.as<unsigned int>(),
                                              gpos.as<unsigned int>(), n + 1, st));
  launchTileLists(d_heads, d_tile_idx, d_order, d_voted, vpos.as<unsigned int>(),
                  gpos.as<unsigned int>(), n, tile_begin.as<unsigned int>(),
                  vlist.as<unsigned int>(), glist.as<unsigned int>(), st);
  const unsigned int* d_ntiles = d_tile_idx + n;
  const unsigned int* d_gcount = gpos.as<unsigned int>() + n;
  PlaneDev* d_planes = planes.as<PlaneDev>();
  const int plane_blocks = static_cast<int>(std::min<std::uint64_t>(tiles_max + 1, 8ull * sms));
  launchPlanes(d_xyz, d_tkeys, ybits, tile_begin.as<unsigned int>(), d_ntiles,
               vpos.as<unsigned int>(), vlist.as<unsigned int>(), glist.as<unsigned int>(),
               d_gcount, gp, d_planes, workPlanes(), needGlobal(), sensorCounts(),
               refine.as<double>(), tiles_max, plane_blocks, st);
  std::uint8_t* d_labels = labels.as<std::uint8_t>();
  GF_CUDA_CHECK(cudaMemsetAsync(d_labels, 0, n_in, st));
  const int classify_blocks = static_cast<int>(std::min<std::uint64_t>(tiles_max, 8ull * sms));
  launchRaisedTiles(d_tkeys, ybits, tile_begin.as<unsigned int>(), d_ntiles,
                    vpos.as<unsigned int>(), gp, d_planes, bb.min_x, bb.min_y, tile,
                    donor.as<int>(), tiles_max, st);
  launchClassify(d_xyz, src.as<unsigned int>(), d_order, d_voted, tile_begin.as<unsigned int>(),
                 d_ntiles, vpos.as<unsigned int>(), vlist.as<unsigned int>(), gp, d_planes,
                 donor.as<int>(), d_labels, groundCount(), workClassify(), classify_blocks, st);
}

// ---- local ground plane (CPU: LocalGroundStage), on the KNN's lists of the sampled points
void CudaNormalPipeline::Impl::localGround(CudaKnn::Impl& im, int n, int m,
                                           const unsigned int* d_sidx, const GroundParamsDev& gp) {
  // cand (the candidates, n bytes) is free after the vote: the sampled points' labels; gflags
  // (n + 1 entries) after the tile lists' scan: each sampled point's KNN row.
  launchLocalGround(xyz.as<float>(), src.as<unsigned int>(), im.sorted.as<float4>(),
                    im.out_idx.as<std::int32_t>(), n, m, d_sidx, gp, cand.as<std::uint8_t>(),
                    gflags.as<unsigned int>(), labels.as<std::uint8_t>(), groundCount(), im.stream);
}

// ---- labels (and counts) down
unsigned int CudaNormalPipeline::Impl::downloadLabels(CudaKnn::Impl& im, std::size_t n_in,
                                                      std::uint8_t* out) {
  cudaStream_t st = im.stream;
  const std::size_t u32 = sizeof(unsigned int);
  char* hs = h_small.as<char>();
  const unsigned int* d_ntiles = pos.as<unsigned int>() + timings.valid_points;
  GF_CUDA_CHECK(cudaMemcpyAsync(h_labels.ptr, labels.ptr, n_in, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaMemcpyAsync(hs + 32, groundCount(), u32, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaMemcpyAsync(hs + 36, d_ntiles, u32, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaMemcpyAsync(hs + 44, candCount(), u32, cudaMemcpyDeviceToHost, st));
  GF_CUDA_CHECK(cudaEventRecord(ev[7], st));
  GF_CUDA_CHECK(cudaStreamSynchronize(st));
  parallelCopy(out, h_labels.ptr, n_in);
  unsigned int ground = 0, ntiles = 0;
  std::memcpy(&ground, hs + 32, u32);
  std::memcpy(&ntiles, hs + 36, u32);
  CudaNormalTimings& tm = timings;
  tm.ground_points = ground;
  tm.tiles = ntiles;
  auto span = [&](int a, int b) {
    float ms = 0.f;
    GF_CUDA_CHECK(cudaEventElapsedTime(&ms, ev[a], ev[b]));
    return static_cast<double>(ms);
  };
  tm.upload_ms = span(0, 1);
  tm.sort_ms = span(1, 2);
  tm.knn_ms = span(2, 3);
  tm.pca_ms = span(3, 4);
  tm.vote_ms = span(4, 5);
  tm.plane_ms = span(5, 6);
  tm.download_ms = span(6, 7);
  unsigned int candidates = 0;
  std::memcpy(&candidates, hs + 44, u32);
  return candidates;
}

}  // namespace ground_filter
