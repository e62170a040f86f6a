#include "knn/kdtree_neighbor_search.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/threads_timing.h"
#include "knn/kdtree_tree.h"
#include "simd/simd.h"

// The tree and the query loop: kdtree_tree.h; the build: kdtree_build.cpp; the SIMD top-K sets:
// kdtree_query_avx512.cpp, kdtree_query_avx2.cpp. This file: the portable set, the backend.

namespace ground_filter {

namespace kdtree {

void queryRangeScalar(const Tree& t, std::size_t pb, std::size_t pe, int k, std::int32_t* out_idx,
                      float* out_dist) {
  SortedKeys set;
  queryRange(t, pb, pe, k, &set, out_idx, out_dist);
}

/// Every pair (clouds smaller than K): rows of `found` sorted keys, then padding.
}  // namespace kdtree

namespace {

using kdtree::keyDist;
using kdtree::makeKey;

void bruteForce(const float* xyz, std::size_t n, int k, NeighborLists* out) {
  // n < K: on the stack for every K the filters accept (no allocation per scan).
  std::uint64_t small[256];
  std::vector<std::uint64_t> large(n > 256 ? n : 0);
  std::uint64_t* const keys = n > 256 ? large.data() : small;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      const float dx = xyz[3 * i] - xyz[3 * j], dy = xyz[3 * i + 1] - xyz[3 * j + 1],
                  dz = xyz[3 * i + 2] - xyz[3 * j + 2];
      keys[j] = makeKey(dx * dx + dy * dy + dz * dz, static_cast<std::uint32_t>(j));
    }
    std::sort(keys, keys + n);
    std::int32_t* row = &out->indices[i * k];
    float* dist = &out->sq_dists[i * k];
    for (int j = 0; j < k; ++j) {
      const bool ok = static_cast<std::size_t>(j) < n;
      row[j] = ok ? static_cast<std::int32_t>(static_cast<std::uint32_t>(keys[j])) : -1;
      dist[j] = ok ? keyDist(keys[j]) : std::numeric_limits<float>::infinity();
    }
  }
}

}  // namespace

using kdtree::KdTree;

struct KdTreeNeighborSearch::Impl {
  KdTree tree;
  std::vector<std::int32_t> rows;  // kept lists: row p = tree position p, indices only
};

KdTreeNeighborSearch::KdTreeNeighborSearch(int threads, int leaf_size)
    : impl_(std::make_unique<Impl>()),
      threads_(resolveThreads(threads)),
      leaf_size_(std::max(1, leaf_size)),
      use_avx512_(kdtree::cpuHasAvx512()),
      has_avx2_(kdtree::cpuHasAvx2()) {}

KdTreeNeighborSearch::~KdTreeNeighborSearch() = default;

void KdTreeNeighborSearch::setUseAvx512(bool use) { use_avx512_ = use && kdtree::cpuHasAvx512(); }

void KdTreeNeighborSearch::search(const float* xyz, std::size_t n, int k, NeighborLists* out) {
  run(xyz, n, k, out, nullptr);
}

bool KdTreeNeighborSearch::searchWithPca(const float* xyz, std::size_t n, int k, NeighborLists* out,
                                         std::vector<PointPca>* pca) {
  run(xyz, n, k, out, pca);
  return true;
}

bool KdTreeNeighborSearch::searchWithCandidates(const float* xyz, std::size_t n, int k,
                                                const CandidateTest& test, NeighborLists* out,
                                                std::uint8_t* candidate) {
  run(xyz, n, k, out, nullptr, &test, candidate);
  return true;
}

const std::vector<std::pair<std::string, double>>& KdTreeNeighborSearch::lastStageMs() const {
  // Refilled in place: the names fit std::string's inline buffer, the vector keeps its capacity.
  stage_ms_.resize(with_pca_ ? 3 : 2);
  stage_ms_[0].first = "kdtree_build";
  stage_ms_[0].second = build_ms_;
  stage_ms_[1].first = "knn";
  stage_ms_[1].second = query_ms_;
  if (with_pca_) {
    stage_ms_[2].first = "pca";
    stage_ms_[2].second = pca_ms_;
  }
  return stage_ms_;
}

void KdTreeNeighborSearch::run(const float* xyz, std::size_t n, int k, NeighborLists* out,
                               std::vector<PointPca>* pca, const CandidateTest* test,
                               std::uint8_t* candidate) {
  if (n > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw std::invalid_argument("KdTreeNeighborSearch: " + std::to_string(n) +
                                " points, more than the int32 neighbour indices can address");
  }
  const auto t0 = Clock::now();
  const std::size_t kk = static_cast<std::size_t>(std::max(k, 0));
  out->k = static_cast<int>(kk);
  out->points = n;
  // Kept lists (searchWithPca() or searchWithCandidates() after keepLists(true)): rows in
  // tree order, written one after the other and without distances; writing rows in input order
  // scatters them over 2 * n * K * 4 bytes, a cache miss per row.
  const bool cand = test != nullptr;  // candidate flags instead of the PCA
  const bool kept = keep_lists_ && (pca != nullptr || cand) && n >= kk && kk > 0;
  lists_kept_ = kept;
  if (kept) {
    out->indices.clear();
    out->sq_dists.clear();
    impl_->rows.resize(n * kk);
  } else {
    out->indices.resize(n * kk);
    out->sq_dists.resize(n * kk);
  }
  build_ms_ = query_ms_ = pca_ms_ = 0.0;
  with_pca_ = pca != nullptr || cand;
  counts_ = CandidateCounts();
  if (pca) pca->resize(n);
  if (n == 0 || kk == 0) {
    if (pca) std::fill(pca->begin(), pca->end(), PointPca());
    if (cand) std::fill(candidate, candidate + n, std::uint8_t{0});
    return;
  }
  if (n < kk) {  // every row holds the whole cloud
    bruteForce(xyz, n, static_cast<int>(kk), out);
    query_ms_ = msSince(t0);
    if (pca) {
      const auto t1 = Clock::now();
      computeNeighborhoodPca(xyz, *out, 1, pca);
      pca_ms_ = msSince(t1);
    }
    if (cand) {
      const auto t1 = Clock::now();
      computeNeighborhoodCandidates(xyz, *out, 1, *test, candidate, &counts_);
      pca_ms_ = msSince(t1);
    }
    return;
  }

  KdTree& im = impl_->tree;
  im.leaf = static_cast<std::uint32_t>(leaf_size_);
  const int threads = static_cast<int>(std::min<std::size_t>(threads_, n / 256 + 1));
  im.build(xyz, n, static_cast<int>(kk), threads);
  build_ms_ = msSince(t0);
  queryChunks(xyz, kk, kept, out, pca, test, candidate, threads);
}

void KdTreeNeighborSearch::queryChunks(const float* xyz, std::size_t kk, bool kept,
                                       NeighborLists* out, std::vector<PointPca>* pca,
                                       const CandidateTest* test, std::uint8_t* candidate,
                                       int threads) {
  using kdtree::kMaxAvx512K;
  const KdTree& im = impl_->tree;
  const std::size_t n = im.pidx.size();
  const bool cand = test != nullptr;
  const auto t1 = Clock::now();
  // Chunks of consecutive tree positions; each chunk's first query starts unbounded. With PCA,
  // each chunk's lists are used right after they are written, while they are in cache.
  constexpr std::size_t kChunk = 1024;
  const std::int64_t chunks = static_cast<std::int64_t>((n + kChunk - 1) / kChunk);
  const bool avx512 = use_avx512_ && kk <= kMaxAvx512K && simd::allows(simd::Level::kAvx512);
#if GF_HAVE_AVX2_PATHS
  const bool avx2 =
      !avx512 && has_avx2_ && kk <= kdtree::kMaxAvx2K && simd::allows(simd::Level::kAvx2);
#endif
#if GF_HAVE_NEON_PATHS
  const bool neon = kk <= kdtree::kMaxNeonK && simd::allows(simd::Level::kNeon);
#endif
  double knn_cpu = 0.0, pca_cpu = 0.0;  // summed over threads, to split the wall time
  std::size_t c_invalid = 0, c_early = 0, c_fast = 0, c_exact = 0;
  std::int32_t* const out_idx = kept ? impl_->rows.data() : out->indices.data();
  float* const out_dist = kept ? nullptr : out->sq_dists.data();
#pragma omp parallel for num_threads(threads) schedule(dynamic, 1) \
    reduction(+ : knn_cpu, pca_cpu, c_invalid, c_early, c_fast, c_exact)
  for (std::int64_t c = 0; c < chunks; ++c) {
    const std::size_t pb = static_cast<std::size_t>(c) * kChunk, pe = std::min(n, pb + kChunk);
    const auto tq = Clock::now();
#if GF_HAVE_AVX512
    if (avx512) {
      kdtree::queryRangeAvx512(im, pb, pe, static_cast<int>(kk), out_idx, out_dist);
    } else
#endif
#if GF_HAVE_AVX2_PATHS
        if (avx2) {
      kdtree::queryRangeAvx2(im, pb, pe, static_cast<int>(kk), out_idx, out_dist);
    } else
#endif
#if GF_HAVE_NEON_PATHS
        if (neon) {
      kdtree::queryRangeNeon(im, pb, pe, static_cast<int>(kk), out_idx, out_dist);
    } else
#endif
    {
      kdtree::queryRangeScalar(im, pb, pe, static_cast<int>(kk), out_idx, out_dist);
    }
    if (pca) {
      const auto tp = Clock::now();
      knn_cpu += std::chrono::duration<double, std::milli>(tp - tq).count();
      if (kept) {
        computeOrderedRowsPca(xyz, out_idx + pb * kk, static_cast<int>(kk), im.pidx.data() + pb,
                              pe - pb, pca->data());
      } else {
        computeRowsPca(xyz, out_idx, static_cast<int>(kk), im.pidx.data() + pb, pe - pb,
                       pca->data());
      }
      pca_cpu += msSince(tp);
    } else if (cand) {
      const auto tp = Clock::now();
      knn_cpu += std::chrono::duration<double, std::milli>(tp - tq).count();
      CandidateCounts cc;
      if (kept) {
        computeOrderedRowsCandidates(xyz, out_idx + pb * kk, static_cast<int>(kk),
                                     im.pidx.data() + pb, pe - pb, *test, candidate, &cc);
      } else {
        computeRowsCandidates(xyz, out_idx, static_cast<int>(kk), im.pidx.data() + pb, pe - pb,
                              *test, candidate, &cc);
      }
      c_invalid += cc.invalid;
      c_early += cc.early;
      c_fast += cc.fast;
      c_exact += cc.exact;
      pca_cpu += msSince(tp);
    }
  }
  counts_ = CandidateCounts{c_invalid, c_early, c_fast, c_exact};
  (void)avx512;
  const double wall = msSince(t1);
  // Fused: the parts' shares of the thread time, applied to the wall time.
  const double share = with_pca_ && knn_cpu + pca_cpu > 0.0 ? pca_cpu / (knn_cpu + pca_cpu) : 0.0;
  pca_ms_ = wall * share;
  query_ms_ = wall - pca_ms_;
}

bool KdTreeNeighborSearch::keepLists(bool keep) {
  keep_lists_ = keep;
  return keep;
}

bool KdTreeNeighborSearch::countFlaggedNeighbors(const std::uint8_t* flags, std::uint16_t* flagged,
                                                 std::uint16_t* neighbors) {
  if (!lists_kept_) return false;
  const KdTree& t = impl_->tree;
  const std::size_t n = t.pidx.size(), kk = static_cast<std::size_t>(t.k);
  const std::int32_t* rows = impl_->rows.data();
  const int nt = static_cast<int>(std::min<std::size_t>(threads_, n / 4096 + 1));
#pragma omp parallel for num_threads(nt) schedule(static, 4096)
  for (std::int64_t p = 0; p < static_cast<std::int64_t>(n); ++p) {
    const std::int32_t* row = rows + static_cast<std::size_t>(p) * kk;
    int u = 0;
    for (std::size_t j = 0; j < kk; ++j) u += flags[row[j]];
    flagged[t.pidx[p]] = static_cast<std::uint16_t>(u);
    neighbors[t.pidx[p]] = static_cast<std::uint16_t>(kk);  // n >= K: every row is full
  }
  return true;
}

bool KdTreeNeighborSearch::keptRows(const std::int32_t** rows, const std::uint32_t** points) const {
  if (!lists_kept_) return false;
  *rows = impl_->rows.data();
  *points = impl_->tree.pidx.data();
  return true;
}

bool KdTreeNeighborSearch::keptLists(NeighborLists* out) const {
  if (!lists_kept_) return false;
  const KdTree& t = impl_->tree;
  const std::size_t n = t.pidx.size(), kk = static_cast<std::size_t>(t.k);
  out->k = static_cast<int>(kk);
  out->points = n;
  out->indices.resize(n * kk);
  out->sq_dists.assign(n * kk, 0.f);
  for (std::size_t p = 0; p < n; ++p) {
    const std::int32_t* row = impl_->rows.data() + p * kk;
    const std::size_t i = t.pidx[p];
    std::copy_n(row, kk, &out->indices[i * kk]);
    for (std::size_t j = 0; j < kk; ++j) {
      const float* a = t.xyz_in + 3 * i;
      const float* b = t.xyz_in + 3 * static_cast<std::size_t>(row[j]);
      const float dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
      out->sq_dists[i * kk + j] = dx * dx + dy * dy + dz * dz;
    }
  }
  return true;
}

}  // namespace ground_filter
