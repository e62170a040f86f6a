#include "neighbors/kdtree_neighbor_search.h"

#include <omp.h>
#if defined(__SSE__)
#include <xmmintrin.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "simd/avx2_common.h"
#include "simd/avx512_common.h"
#include "normal/neighborhood_pca.h"
#include "simd/simd.h"

#if defined(__GNUC__)
#define GF_KNN_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define GF_KNN_ALWAYS_INLINE inline
#endif

// Exact K nearest neighbours of every point of a cloud among the same points.
//
// - A kd-tree with median splits on the widest side of each node's tight bounding box, leaves of
//   at most `leaf_size` points stored contiguously as x/y/z/index arrays (points of a leaf in
//   index order). A node whose points all coincide is a leaf whatever its size; only its first
//   K points (lowest indices) can be in any list, so only those are scanned.
// - Queries run in tree order, so consecutive queries are close and share cache lines. Each query
//   starts with the bound (d_prev + |q - q_prev|)^2, d_prev the previous query's K-th distance:
//   the previous query's K neighbours lie inside it, so the K-th distance of q does too. A query
//   at the same coordinates as the previous one (a lidar's no-return points at the origin) copies
//   its list.
// - A neighbour list is ordered by the key (squared distance, index): the result is unique, so it
//   is the same for any thread count, traversal order or code path. Squared distances are
//   float ((dx*dx + dy*dy) + dz*dz), never fused multiply-adds, the same value as nanoflann's
//   L2_Simple_Adaptor and the tests' brute force.
// - With AVX-512 (checked at run time) candidates within the bound are computed 16 at a time and
//   kept in a buffer; full buffers are sorted by a bitonic network and merged into the sorted
//   top K (no per-candidate branches). With AVX2 only, the same scheme 8 distances at a time
//   (candidates packed by a permutation table) and 4 keys per register. Otherwise a sorted array
//   with insertion is used. The SIMD level in force (simd.h, GF_SIMD) picks among them.

namespace ground_filter {

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

constexpr std::uint64_t kNoKey = ~0ULL;  // an empty slot: larger than any real key

/// Sort key of a neighbour: squared distance bits (non-negative floats order like their bits),
/// then the point index.
std::uint64_t makeKey(float sq_dist, std::uint32_t idx) {
  std::uint32_t bits;
  std::memcpy(&bits, &sq_dist, sizeof bits);
  return (static_cast<std::uint64_t>(bits) << 32) | idx;
}

float keyDist(std::uint64_t key) {
  const std::uint32_t bits = static_cast<std::uint32_t>(key >> 32);
  float d;
  std::memcpy(&d, &bits, sizeof d);
  return d;
}

struct Point {
  float x, y, z;
  std::uint32_t idx;
};

struct alignas(16) Node {
  float lo[4];  // tight bounding box of the node's points; [3] = 0
  float hi[4];
  std::uint32_t begin;     // first tree position of the node's points
  std::uint32_t scan_end;  // leaf: end of the positions to scan (see kSamePoint)
  std::int32_t left;       // children (left < 0: a leaf)
  std::int32_t right;      // leaf: 1 when all its points coincide (kSamePoint), else 0
};

constexpr std::int32_t kSamePoint = 1;

/// Nodes of a subtree of `size` points when every node of more than `leaf` points is split in
/// halves (nodes whose points all coincide stop earlier and leave their slots unused).
std::uint32_t subtreeNodes(std::uint32_t size, std::uint32_t leaf) {
  // The sizes at one depth are s or s + 1: count the nodes of each.
  std::uint64_t total = 0, small = 1, large = 0;
  std::uint32_t s = size;
  while (small + large > 0) {
    total += small + large;
    const std::uint64_t split_small = s > leaf ? small : 0, split_large = s + 1 > leaf ? large : 0;
    if (s % 2 == 0) {  // s -> s/2 + s/2, s+1 -> s/2 + (s/2 + 1)
      small = 2 * split_small + split_large;
      large = split_large;
    } else {  // s -> (s-1)/2 + (s+1)/2, s+1 -> (s+1)/2 + (s+1)/2
      small = split_small;
      large = split_small + 2 * split_large;
    }
    s /= 2;
  }
  return static_cast<std::uint32_t>(total);
}

/// Points at or above this many build their two subtrees as parallel tasks.
constexpr std::uint32_t kTaskPoints = 8192;

/// Largest K of the AVX-512 code (32 registers of keys); larger K use the portable code.
constexpr std::size_t kMaxAvx512K = 256;

/// The kd-tree over one cloud, its points in tree order as separate coordinate arrays.
struct KdTree {
  std::vector<Point> pts;  // tree order
  std::vector<float> px, py, pz;
  std::vector<std::uint32_t> pidx;
  std::vector<std::uint32_t> leaf_of;     // build only: first tree position of each point's leaf
  std::vector<std::uint32_t> cursor;      // build only: next free position of the leaf at [begin]
  std::vector<std::uint32_t> cursor_end;  // build only: end of the free positions of that leaf
  std::vector<Node> nodes;  // preorder: left child of node i is i + 1; unused slots possible
  std::uint32_t leaf = 16;
  int k = 0;
  const float* xyz_in = nullptr;  // the cloud of the last build (keptLists() only)

  void buildNode(std::uint32_t id, std::uint32_t b, std::uint32_t e);
  void build(const float* xyz, std::size_t n, int k_, int threads);
  void place(const float* xyz, std::size_t i, std::uint32_t p) {
    px[p] = xyz[3 * i];
    py[p] = xyz[3 * i + 1];
    pz[p] = xyz[3 * i + 2];
    pidx[p] = static_cast<std::uint32_t>(i);
  }
};

void KdTree::buildNode(std::uint32_t id, std::uint32_t b, std::uint32_t e) {
  Node& nd = nodes[id];
  alignas(16) float lo[4], hi[4];
#if defined(__SSE__)
  // One SSE register per point (x, y, z, index bits; lane 3 unused). min_ps(p, lo) is
  // p < lo ? p : lo, the same value as std::min(lo, p), also for signed zeros.
  __m128 lo4 = _mm_loadu_ps(&pts[b].x), hi4 = lo4;
  for (std::uint32_t i = b + 1; i < e; ++i) {
    const __m128 p = _mm_loadu_ps(&pts[i].x);
    lo4 = _mm_min_ps(p, lo4);
    hi4 = _mm_max_ps(p, hi4);
  }
  _mm_store_ps(lo, lo4);
  _mm_store_ps(hi, hi4);
#else
  lo[0] = hi[0] = pts[b].x;
  lo[1] = hi[1] = pts[b].y;
  lo[2] = hi[2] = pts[b].z;
  for (std::uint32_t i = b + 1; i < e; ++i) {
    const Point& p = pts[i];
    lo[0] = std::min(lo[0], p.x);
    hi[0] = std::max(hi[0], p.x);
    lo[1] = std::min(lo[1], p.y);
    hi[1] = std::max(hi[1], p.y);
    lo[2] = std::min(lo[2], p.z);
    hi[2] = std::max(hi[2], p.z);
  }
#endif
  for (int d = 0; d < 3; ++d) {
    nd.lo[d] = lo[d];
    nd.hi[d] = hi[d];
  }
  nd.lo[3] = nd.hi[3] = 0.f;
  nd.begin = b;
  nd.scan_end = e;
  nd.left = -1;
  nd.right = 0;
  const float ext[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
  const int dim = ext[0] >= ext[1] ? (ext[0] >= ext[2] ? 0 : 2) : (ext[1] >= ext[2] ? 1 : 2);
  const bool same_point = !(ext[dim] > 0.f);
  if (same_point || e - b <= leaf) {
    // Leaf points go in index order; build() places them (one pass, no sort per leaf).
    for (std::uint32_t i = b; i < e; ++i) leaf_of[pts[i].idx] = b;
    cursor[b] = b;
    cursor_end[b] = e;
    if (same_point) {
      nd.scan_end = std::min<std::uint32_t>(e, b + static_cast<std::uint32_t>(k));
      nd.right = kSamePoint;
    }
    return;
  }
  const std::uint32_t m = b + (e - b) / 2;
  // One comparator per axis: a fixed offset instead of an indexed load in the inner loop.
  const auto first = pts.begin() + b, mid = pts.begin() + m, last = pts.begin() + e;
  if (dim == 0) {
    std::nth_element(first, mid, last, [](const Point& p, const Point& r) { return p.x < r.x; });
  } else if (dim == 1) {
    std::nth_element(first, mid, last, [](const Point& p, const Point& r) { return p.y < r.y; });
  } else {
    std::nth_element(first, mid, last, [](const Point& p, const Point& r) { return p.z < r.z; });
  }
  const std::uint32_t l = id + 1, r = id + 1 + subtreeNodes(m - b, leaf);
  nd.left = static_cast<std::int32_t>(l);
  nd.right = static_cast<std::int32_t>(r);
  if (e - b >= kTaskPoints) {
#pragma omp task default(shared) firstprivate(l, b, m)
    buildNode(l, b, m);
    buildNode(r, m, e);
#pragma omp taskwait
  } else {
    buildNode(l, b, m);
    buildNode(r, m, e);
  }
}

void KdTree::build(const float* xyz, std::size_t n, int k_, int threads) {
  k = k_;
  xyz_in = xyz;
  pts.resize(n);
  px.resize(n);
  py.resize(n);
  pz.resize(n);
  pidx.resize(n);
  leaf_of.resize(n);
  cursor.resize(n);
  cursor_end.resize(n);
  nodes.assign(subtreeNodes(static_cast<std::uint32_t>(n), leaf), Node());
#pragma omp parallel num_threads(threads)
  {
#pragma omp for schedule(static)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
      pts[i] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2], static_cast<std::uint32_t>(i)};
    }
#pragma omp single
    buildNode(0, 0, static_cast<std::uint32_t>(n));
    // (implicit barrier: all tasks are done)
    // Points into their leaves in index order, so that every leaf is sorted by index: the lower
    // half of the indices ascending from each leaf's start, the upper half descending from its
    // end (two threads; they meet where the halves meet).
#pragma omp sections
    {
#pragma omp section
      {
        for (std::size_t i = 0; i < n / 2; ++i) place(xyz, i, cursor[leaf_of[i]]++);
      }
#pragma omp section
      {
        for (std::size_t i = n; i-- > n / 2;) place(xyz, i, --cursor_end[leaf_of[i]]);
      }
    }
  }
}

using Tree = KdTree;

/// Squared distance from q to a node's box, summed like a point distance: never larger than the
/// (float) distance to any point inside the box.
float boxSqDist(const Node& nd, const float* q) {
  float d[3];
  for (int i = 0; i < 3; ++i) {
    d[i] = q[i] < nd.lo[i] ? nd.lo[i] - q[i] : (q[i] > nd.hi[i] ? q[i] - nd.hi[i] : 0.f);
  }
  return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

/// How many leading points of a same-point leaf (indices ascending, all at squared distance d)
/// can still enter a list whose K-th key is `kth` (kNoKey while the list is not full).
int samePointPrefix(const std::uint32_t* ids, int m, float d, std::uint64_t kth) {
  if (kth == kNoKey) return m;
  const std::uint64_t dist_bits = makeKey(d, 0) >> 32, kth_bits = kth >> 32;
  if (dist_bits != kth_bits) return dist_bits < kth_bits ? m : 0;
  return static_cast<int>(std::lower_bound(ids, ids + m, static_cast<std::uint32_t>(kth)) - ids);
}

/// Sorted array of the best K keys, insertion (portable path).
class SortedKeys {
 public:
  SortedKeys() = default;
  SortedKeys(const SortedKeys&) = delete;  // keys_ may point into the object
  SortedKeys& operator=(const SortedKeys&) = delete;
  void init(int k, float bound) {
    // K <= kInlineKeys (every K the filters accept) in the object itself: a set per chunk of
    // queries then allocates nothing; a larger K (direct callers) on the heap.
    if (k <= kInlineKeys) {
      keys_ = inline_keys_;
    } else {
      heap_keys_.resize(static_cast<std::size_t>(k));
      keys_ = heap_keys_.data();
    }
    k_ = k;
    count_ = 0;
    thr_ = bound;
  }
  float threshold() const { return thr_; }
  static float boxDist(const Node& nd, const float* q) { return boxSqDist(nd, q); }
  void scan(const Tree& t, const Node& nd, const float* q) {
    const std::uint32_t b = nd.begin;
    int m = static_cast<int>(nd.scan_end - b);
    const float *x = t.px.data() + b, *y = t.py.data() + b, *z = t.pz.data() + b;
    if (nd.right == kSamePoint) {
      const float dx = q[0] - x[0], dy = q[1] - y[0], dz = q[2] - z[0];
      m = samePointPrefix(t.pidx.data() + b, m, dx * dx + dy * dy + dz * dz,
                          count_ == k_ ? keys_[k_ - 1] : kNoKey);
    }
    float d[256];
    for (int j0 = 0; j0 < m; j0 += 256) {
      const int c = std::min(256, m - j0);
      for (int j = 0; j < c; ++j) {
        const float dx = q[0] - x[j0 + j], dy = q[1] - y[j0 + j], dz = q[2] - z[j0 + j];
        d[j] = dx * dx + dy * dy + dz * dz;
      }
      for (int j = 0; j < c; ++j) {
        if (d[j] <= thr_) add(makeKey(d[j], t.pidx[b + j0 + j]));
      }
    }
  }
  void finish() {}
  bool complete() const { return count_ == k_; }
  std::uint64_t key(int j) const { return keys_[j]; }
  void write(std::int32_t* idx, float* dist) const {
    for (int j = 0; j < k_; ++j) {
      idx[j] = static_cast<std::int32_t>(static_cast<std::uint32_t>(keys_[j]));
      if (dist) dist[j] = keyDist(keys_[j]);
    }
  }

 private:
  void add(std::uint64_t key) {
    int i = count_;
    if (count_ == k_) {
      if (key >= keys_[k_ - 1]) return;
      i = k_ - 1;
    } else {
      ++count_;
    }
    for (; i > 0 && keys_[i - 1] > key; --i) keys_[i] = keys_[i - 1];
    keys_[i] = key;
    if (count_ == k_) thr_ = keyDist(keys_[k_ - 1]);
  }
  static constexpr int kInlineKeys = 256;
  std::uint64_t inline_keys_[kInlineKeys];
  std::vector<std::uint64_t> heap_keys_;
  std::uint64_t* keys_ = inline_keys_;
  int k_ = 0, count_ = 0;
  float thr_ = 0.f;
};

/// Depth-first search from the root, nearer child first, pruning boxes farther than the set's
/// current threshold (the set scans the leaves). `q` points to 4 floats, q[3] = 0.
template <class Set>
GF_KNN_ALWAYS_INLINE void descend(const Tree& t, const float* q, Set* set) {
  struct Item {
    std::int32_t node;
    float dist;
  };
  Item stack[128];  // depth <= log2(2^32 / leaf) + 1
  int sp = 0;
  stack[sp++] = {0, 0.f};
  while (sp > 0) {
    const Item it = stack[--sp];
    if (it.dist > set->threshold()) continue;
    std::int32_t id = it.node;
    for (;;) {
      const Node& nd = t.nodes[id];
      if (nd.left < 0) {
        set->scan(t, nd, q);
        break;
      }
      const float dl = Set::boxDist(t.nodes[nd.left], q);
      const float dr = Set::boxDist(t.nodes[nd.right], q);
      // Nearer child next, the other one on the stack if it is within reach (no branches: which
      // side is nearer is unpredictable).
      const bool right_first = dr < dl;
      const std::int32_t near = right_first ? nd.right : nd.left;
      const std::int32_t far = right_first ? nd.left : nd.right;
      const float d_near = right_first ? dr : dl, d_far = right_first ? dl : dr;
      stack[sp] = {far, d_far};
      sp += d_far <= set->threshold();
      if (d_near > set->threshold()) break;
      id = near;
    }
  }
  set->finish();
}

/// Queries the points at tree positions [pb, pe) in order, each bounded by the previous one.
/// Row of the point at tree position p: its point index (input order), or p itself when
/// `out_dist` is null (the kept layout: indices only, written sequentially).
template <class Set>
GF_KNN_ALWAYS_INLINE void queryRange(const Tree& t, std::size_t pb, std::size_t pe, int k, Set* set,
                                     std::int32_t* out_idx, float* out_dist) {
  const float inf = std::numeric_limits<float>::infinity();
  const std::size_t kk = static_cast<std::size_t>(k);
  float prev[3] = {0.f, 0.f, 0.f};
  double prev_kth = -1.0;
  std::size_t prev_row = 0;
  for (std::size_t p = pb; p < pe; ++p) {
    alignas(16) const float q[4] = {t.px[p], t.py[p], t.pz[p], 0.f};
    const std::size_t row = (out_dist ? static_cast<std::size_t>(t.pidx[p]) : p) * kk;
    if (prev_kth >= 0.0 && q[0] == prev[0] && q[1] == prev[1] && q[2] == prev[2]) {
      // The same point again (e.g. a lidar's no-return points at the origin): same list.
      std::copy_n(out_idx + prev_row, kk, out_idx + row);
      if (out_dist) std::copy_n(out_dist + prev_row, kk, out_dist + row);
      continue;
    }
    float bound = inf;
    if (prev_kth >= 0.0) {
      const double dx = static_cast<double>(q[0]) - prev[0],
                   dy = static_cast<double>(q[1]) - prev[1],
                   dz = static_cast<double>(q[2]) - prev[2];
      const double r = std::sqrt(prev_kth) + std::sqrt(dx * dx + dy * dy + dz * dz);
      // The margin covers the float rounding of the distances (a few ulp); a bound that is too
      // small anyway is caught below.
      bound = static_cast<float>(r * r * (1.0 + 1e-5) + 1e-30);
    }
    set->init(k, bound);
    descend(t, q, set);
    if (!set->complete()) {  // fewer than K points within the bound: not expected, but be safe
      set->init(k, inf);
      descend(t, q, set);
    }
    set->write(out_idx + row, out_dist ? out_dist + row : nullptr);
    std::copy_n(q, 3, prev);
    prev_kth = keyDist(set->key(k - 1));
    prev_row = row;
  }
}

#if GF_HAVE_AVX512

// GCC's intrinsics start some results from _mm512_undefined_*(), which -Wmaybe-uninitialized
// reports at every inlined use (a known false positive).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

using simd::opaque;

// Bitonic network on R zmm registers of 8 uint64 keys each, ascending.

GF_TARGET_AVX512 inline __m512i reverseLanes(__m512i v) {
  return _mm512_permutexvar_epi64(_mm512_set_epi64(0, 1, 2, 3, 4, 5, 6, 7), v);
}

/// Compare-exchange of every lane with lane ^ M; lanes with bit H set keep the larger key.
template <int M, int H>
GF_TARGET_AVX512 inline __m512i laneStep(__m512i v) {
  const __m512i idx = _mm512_set_epi64(7 ^ M, 6 ^ M, 5 ^ M, 4 ^ M, 3 ^ M, 2 ^ M, 1 ^ M, 0 ^ M);
  const __m512i p = _mm512_permutexvar_epi64(idx, v);
  constexpr __mmask8 kHigh = H == 1 ? 0xAA : H == 2 ? 0xCC : 0xF0;
  return _mm512_mask_blend_epi64(kHigh, _mm512_min_epu64(v, p), _mm512_max_epu64(v, p));
}

/// Sorts each register's lanes given that they form a bitonic sequence.
GF_TARGET_AVX512 inline __m512i laneMerge(__m512i v) {
  return laneStep<1, 1>(laneStep<2, 2>(laneStep<4, 4>(v)));
}

/// Register-level half-cleaners over v[0..R) at distances s_max, s_max / 2, ..., 1, then each
/// register's lanes: sorts every run of 2 s_max registers that is a bitonic sequence.
template <int R>
GF_TARGET_AVX512 inline void halfCleanAndMerge(__m512i* v, int s_max) {
  for (int s = s_max; s >= 1; s /= 2) {
    for (int i = 0; i < R; ++i) {
      if (i & s) continue;
      const __m512i a = v[i], b = v[i + s];
      v[i] = _mm512_min_epu64(a, b);
      v[i + s] = _mm512_max_epu64(a, b);
    }
  }
  for (int i = 0; i < R; ++i) v[i] = laneMerge(v[i]);
}

/// Sorts the bitonic sequence v[0..R).
template <int R>
GF_TARGET_AVX512 inline void bitonicMerge(__m512i* v) {
  halfCleanAndMerge<R>(v, R / 2);
}

GF_TARGET_AVX512 inline void compareExchange(__m512i* a, __m512i* b) {
  const __m512i lo = _mm512_min_epu64(*a, *b);
  *b = _mm512_max_epu64(*a, *b);
  *a = lo;
}

/// Sorts each of 8 registers: an 8-input sorting network across the registers (every lane
/// position sorted), then an 8 x 8 transpose.
GF_TARGET_AVX512 inline void sortRegisters8(__m512i* v) {
  // The optimal 19-comparator network for 8 inputs (Knuth, TAOCP 5.3.4).
  compareExchange(&v[0], &v[2]);
  compareExchange(&v[1], &v[3]);
  compareExchange(&v[4], &v[6]);
  compareExchange(&v[5], &v[7]);
  compareExchange(&v[0], &v[4]);
  compareExchange(&v[1], &v[5]);
  compareExchange(&v[2], &v[6]);
  compareExchange(&v[3], &v[7]);
  compareExchange(&v[0], &v[1]);
  compareExchange(&v[2], &v[3]);
  compareExchange(&v[4], &v[5]);
  compareExchange(&v[6], &v[7]);
  compareExchange(&v[2], &v[4]);
  compareExchange(&v[3], &v[5]);
  compareExchange(&v[1], &v[4]);
  compareExchange(&v[3], &v[6]);
  compareExchange(&v[1], &v[2]);
  compareExchange(&v[3], &v[4]);
  compareExchange(&v[5], &v[6]);
  __m512i t[8], u[8];
  for (int i = 0; i < 4; ++i) {
    t[2 * i] = _mm512_unpacklo_epi64(v[2 * i], v[2 * i + 1]);
    t[2 * i + 1] = _mm512_unpackhi_epi64(v[2 * i], v[2 * i + 1]);
  }
  for (int h = 0; h < 2; ++h) {  // 128-bit lanes 0 and 2, then 1 and 3
    u[4 * h + 0] = _mm512_shuffle_i64x2(t[4 * h + 0], t[4 * h + 2], 0x88);
    u[4 * h + 1] = _mm512_shuffle_i64x2(t[4 * h + 0], t[4 * h + 2], 0xdd);
    u[4 * h + 2] = _mm512_shuffle_i64x2(t[4 * h + 1], t[4 * h + 3], 0x88);
    u[4 * h + 3] = _mm512_shuffle_i64x2(t[4 * h + 1], t[4 * h + 3], 0xdd);
  }
  v[0] = _mm512_shuffle_i64x2(u[0], u[4], 0x88);
  v[4] = _mm512_shuffle_i64x2(u[0], u[4], 0xdd);
  v[1] = _mm512_shuffle_i64x2(u[2], u[6], 0x88);
  v[5] = _mm512_shuffle_i64x2(u[2], u[6], 0xdd);
  v[2] = _mm512_shuffle_i64x2(u[1], u[5], 0x88);
  v[6] = _mm512_shuffle_i64x2(u[1], u[5], 0xdd);
  v[3] = _mm512_shuffle_i64x2(u[3], u[7], 0x88);
  v[7] = _mm512_shuffle_i64x2(u[3], u[7], 0xdd);
}

/// Sorts the 8R keys of v ascending.
template <int R>
GF_TARGET_AVX512 inline void bitonicSort(__m512i* v) {
  if (R % 8 == 0) {
    for (int i = 0; i < R; i += 8) sortRegisters8(v + i);
  } else {
    for (int i = 0; i < R; ++i) {
      __m512i x = laneStep<1, 1>(v[i]);
      x = laneStep<1, 1>(laneStep<3, 2>(x));
      v[i] = laneStep<1, 1>(laneStep<2, 2>(laneStep<7, 4>(x)));
    }
  }
  for (int size = 2; size <= R; size *= 2) {  // merge sorted runs of size / 2 registers
    for (int blk = 0; blk < R; blk += size) {
      for (int j = 0; j < size / 2; ++j) {
        const __m512i a = v[blk + j], b = reverseLanes(v[blk + size - 1 - j]);
        v[blk + j] = _mm512_min_epu64(a, b);
        v[blk + size - 1 - j] = reverseLanes(_mm512_max_epu64(a, b));
      }
    }
    halfCleanAndMerge<R>(v, size / 4);
  }
}

/// The best K <= 8R keys, sorted, fed by a buffer of candidates within the threshold.
template <int R>
class TopKAvx512 {
 public:
  static constexpr int kSlots = 8 * R;

  GF_TARGET_AVX512 void init(int k, float bound) {
    k_ = k;
    pending_ = 0;
    thr_ = bound;
    empty_ = true;
  }
  float threshold() const { return thr_; }

  GF_TARGET_AVX512 static float boxDist(const Node& nd, const float* q) {
    const __m128 q4 = _mm_load_ps(q);  // q[3] = 0, like the boxes' padding
    const __m128 lo = _mm_load_ps(nd.lo), hi = _mm_load_ps(nd.hi);
    const __m128 t =
        _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, q4), _mm_sub_ps(q4, hi)), _mm_setzero_ps());
    const __m128 t2 = opaque(_mm_mul_ps(t, t));
    return (_mm_cvtss_f32(t2) + _mm_cvtss_f32(_mm_shuffle_ps(t2, t2, 1))) +
           _mm_cvtss_f32(_mm_shuffle_ps(t2, t2, 2));
  }

  GF_TARGET_AVX512 void scan(const Tree& t, const Node& nd, const float* q) {
    const std::uint32_t b = nd.begin;
    int m = static_cast<int>(nd.scan_end - b);
    const float *x = t.px.data() + b, *y = t.py.data() + b, *z = t.pz.data() + b;
    const std::uint32_t* ids = t.pidx.data() + b;
    if (nd.right == kSamePoint && !empty_) {
      const __m128 dx = _mm_sub_ss(_mm_set_ss(q[0]), _mm_set_ss(x[0]));
      const __m128 dy = _mm_sub_ss(_mm_set_ss(q[1]), _mm_set_ss(y[0]));
      const __m128 dz = _mm_sub_ss(_mm_set_ss(q[2]), _mm_set_ss(z[0]));
      const __m128 d =
          _mm_add_ss(_mm_add_ss(opaque(_mm_mul_ss(dx, dx)), opaque(_mm_mul_ss(dy, dy))),
                     opaque(_mm_mul_ss(dz, dz)));
      m = samePointPrefix(ids, m, _mm_cvtss_f32(d), top_[k_ - 1]);
    }
    const __m512 qx = _mm512_set1_ps(q[0]), qy = _mm512_set1_ps(q[1]), qz = _mm512_set1_ps(q[2]);
    // pending_ and the threshold in registers: the candidate stores could alias the members, so
    // the compiler reloaded them after every block (a store-forwarding round trip on the
    // loop-carried count).
    int pending = pending_;
    __m512 thr = _mm512_set1_ps(thr_);
    for (int j = 0; j < m; j += 16) {
      const __mmask16 in = static_cast<__mmask16>(m - j >= 16 ? 0xffff : (1u << (m - j)) - 1);
      const __m512 dx = _mm512_sub_ps(qx, _mm512_maskz_loadu_ps(in, x + j));
      const __m512 dy = _mm512_sub_ps(qy, _mm512_maskz_loadu_ps(in, y + j));
      const __m512 dz = _mm512_sub_ps(qz, _mm512_maskz_loadu_ps(in, z + j));
      const __m512 d =
          _mm512_add_ps(_mm512_add_ps(opaque(_mm512_mul_ps(dx, dx)), opaque(_mm512_mul_ps(dy, dy))),
                        opaque(_mm512_mul_ps(dz, dz)));
      const __mmask16 keep = _mm512_mask_cmp_ps_mask(in, d, thr, _CMP_LE_OQ);
      // No branch on `keep`: a candidate is found in about one block in four, unpredictably.
      // Compress in a register, then a plain store (compress-to-memory is slow on some CPUs).
      _mm512_storeu_si512(cand_d_ + pending,
                          _mm512_maskz_compress_epi32(keep, _mm512_castps_si512(d)));
      _mm512_storeu_si512(cand_i_ + pending,
                          _mm512_maskz_compress_epi32(keep, _mm512_maskz_loadu_epi32(in, ids + j)));
      pending += __builtin_popcount(keep);
      if (pending >= kSlots) {
        const int extra = pending - kSlots;
        pending_ = kSlots;
        flush();
        // Move the candidates past the flushed block to the front.
        // (extra < 16: one register each, from the 16 slots past kSlots)
        _mm512_store_si512(cand_d_, _mm512_load_si512(cand_d_ + kSlots));
        _mm512_store_si512(cand_i_, _mm512_load_si512(cand_i_ + kSlots));
        pending = extra;
        thr = _mm512_set1_ps(thr_);
      }
    }
    pending_ = pending;
  }

  GF_TARGET_AVX512 void finish() {
    if (pending_ > 0 || empty_) flush();
  }
  bool complete() const { return top_[k_ - 1] != kNoKey; }
  std::uint64_t key(int j) const { return top_[j]; }

  GF_TARGET_AVX512 void write(std::int32_t* idx, float* dist) const {
    const __m512i lo_sel =
        _mm512_set_epi32(30, 28, 26, 24, 22, 20, 18, 16, 14, 12, 10, 8, 6, 4, 2, 0);
    const __m512i hi_sel =
        _mm512_set_epi32(31, 29, 27, 25, 23, 21, 19, 17, 15, 13, 11, 9, 7, 5, 3, 1);
    for (int j = 0; j < k_; j += 16) {
      const __mmask16 m = static_cast<__mmask16>(k_ - j >= 16 ? 0xffff : (1u << (k_ - j)) - 1);
      const __m512i a = _mm512_load_si512(top_ + j), b = _mm512_load_si512(top_ + j + 8);
      const __m512i ids = _mm512_permutex2var_epi32(a, lo_sel, b);
      // Plain stores for full blocks: masked stores to memory are slow on Zen 4.
      if (m == 0xffff) {
        _mm512_storeu_si512(idx + j, ids);
        if (dist) _mm512_storeu_si512(dist + j, _mm512_permutex2var_epi32(a, hi_sel, b));
      } else {
        _mm512_mask_storeu_epi32(idx + j, m, ids);
        if (dist) _mm512_mask_storeu_epi32(dist + j, m, _mm512_permutex2var_epi32(a, hi_sel, b));
      }
    }
  }

 private:
  /// Sorts the pending candidates and merges them into the top list.
  GF_TARGET_AVX512 void flush() {
    __m512i c[R];
    const __m512i none = _mm512_set1_epi64(-1);
    for (int r = 0; r < R; ++r) {
      const int cnt = std::max(0, std::min(8, pending_ - 8 * r));
      const __mmask8 m = static_cast<__mmask8>((1u << cnt) - 1);
      const __m256i d = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(cand_d_ + 8 * r));
      const __m256i i = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(cand_i_ + 8 * r));
      const __m512i key = _mm512_or_si512(_mm512_slli_epi64(_mm512_cvtepu32_epi64(d), 32),
                                          _mm512_cvtepu32_epi64(i));
      c[r] = _mm512_mask_blend_epi64(m, none, key);
    }
    // Registers past the candidates hold only empty slots: sort just the used ones.
    const int used = (pending_ + 7) / 8;
    if (used <= 1) {
      bitonicSort<1>(c);
    } else if (R >= 2 && used <= 2) {
      bitonicSort<(R >= 2 ? 2 : 1)>(c);
    } else if (R >= 4 && used <= 4) {
      bitonicSort<(R >= 4 ? 4 : 1)>(c);
    } else {
      bitonicSort<R>(c);
    }
    if (empty_) {
      for (int r = 0; r < R; ++r) _mm512_store_si512(top_ + 8 * r, c[r]);
      empty_ = false;
    } else {
      // Smallest 8R of two sorted lists: min(top[i], c[8R-1-i]) is bitonic; merge it.
      __m512i t[R];
      for (int r = 0; r < R; ++r) {
        t[r] = _mm512_min_epu64(_mm512_load_si512(top_ + 8 * r), reverseLanes(c[R - 1 - r]));
      }
      bitonicMerge<R>(t);
      for (int r = 0; r < R; ++r) _mm512_store_si512(top_ + 8 * r, t[r]);
    }
    pending_ = 0;
    const std::uint64_t kth = top_[k_ - 1];
    if (kth != kNoKey) thr_ = std::min(thr_, keyDist(kth));
  }

  alignas(64) std::uint64_t top_[kSlots];
  alignas(64) std::uint32_t cand_d_[kSlots + 16];  // squared distance bits
  alignas(64) std::uint32_t cand_i_[kSlots + 16];  // point indices
  int k_ = 0, pending_ = 0;
  float thr_ = 0.f;
  bool empty_ = true;
};

GF_TARGET_AVX512 void queryRangeAvx512(const Tree& t, std::size_t pb, std::size_t pe, int k,
                                       std::int32_t* out_idx, float* out_dist) {
  if (k <= 64) {
    TopKAvx512<8> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 128) {
    TopKAvx512<16> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else {
    TopKAvx512<32> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  }
}

#pragma GCC diagnostic pop

bool cpuHasAvx512() { return simd::cpuHasAvx512(); }

#else

bool cpuHasAvx512() { return false; }

#endif  // GF_HAVE_AVX512

#if GF_HAVE_AVX2_PATHS

// AVX2 (no AVX-512): the same scheme as TopKAvx512, four 64-bit keys per register. AVX2 has no
// unsigned 64-bit min/max: keys are compared as signed (a key's distance bits are those of a
// non-negative float, so real keys are below 2^63) and an empty slot is INT64_MAX instead of
// kNoKey.

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

constexpr std::uint64_t kNoKeyAvx2 = 0x7fffffffffffffffULL;

/// Largest K of the AVX2 code (64 registers of keys); larger K use the portable code.
constexpr std::size_t kMaxAvx2K = 256;

GF_TARGET_AVX2_PATHS inline void compareExchange4(__m256i* a, __m256i* b) {
  const __m256i gt = _mm256_cmpgt_epi64(*a, *b);
  const __m256i lo = _mm256_blendv_epi8(*a, *b, gt);
  *b = _mm256_blendv_epi8(*b, *a, gt);
  *a = lo;
}

GF_TARGET_AVX2_PATHS inline __m256i reverseLanes4(__m256i v) {
  return _mm256_permute4x64_epi64(v, 0x1b);
}

/// Sorts a register's 4 lanes given that they form a bitonic sequence.
GF_TARGET_AVX2_PATHS inline __m256i laneMerge4(__m256i v) {
  __m256i p = _mm256_permute4x64_epi64(v, 0x4e);  // lanes 2 3 0 1
  __m256i gt = _mm256_cmpgt_epi64(v, p);
  v = _mm256_blend_epi32(_mm256_blendv_epi8(v, p, gt), _mm256_blendv_epi8(p, v, gt), 0xf0);
  p = _mm256_shuffle_epi32(v, 0x4e);  // lanes 1 0 3 2
  gt = _mm256_cmpgt_epi64(v, p);
  return _mm256_blend_epi32(_mm256_blendv_epi8(v, p, gt), _mm256_blendv_epi8(p, v, gt), 0xcc);
}

/// Register-level half-cleaners over v[0..R) at distances s_max, ..., 1, then each register's
/// lanes (see halfCleanAndMerge()).
template <int R>
GF_TARGET_AVX2_PATHS inline void halfCleanAndMerge4(__m256i* v, int s_max) {
  for (int s = s_max; s >= 1; s /= 2) {
    for (int i = 0; i < R; ++i) {
      if (i & s) continue;
      compareExchange4(&v[i], &v[i + s]);
    }
  }
  for (int i = 0; i < R; ++i) v[i] = laneMerge4(v[i]);
}

/// Sorts each of 4 registers: a 4-input sorting network across them, then a 4 x 4 transpose.
GF_TARGET_AVX2_PATHS inline void sortRegisters4(__m256i* v) {
  compareExchange4(&v[0], &v[1]);
  compareExchange4(&v[2], &v[3]);
  compareExchange4(&v[0], &v[2]);
  compareExchange4(&v[1], &v[3]);
  compareExchange4(&v[1], &v[2]);
  const __m256i t0 = _mm256_unpacklo_epi64(v[0], v[1]), t1 = _mm256_unpackhi_epi64(v[0], v[1]);
  const __m256i t2 = _mm256_unpacklo_epi64(v[2], v[3]), t3 = _mm256_unpackhi_epi64(v[2], v[3]);
  v[0] = _mm256_permute2x128_si256(t0, t2, 0x20);
  v[1] = _mm256_permute2x128_si256(t1, t3, 0x20);
  v[2] = _mm256_permute2x128_si256(t0, t2, 0x31);
  v[3] = _mm256_permute2x128_si256(t1, t3, 0x31);
}

/// Sorts the 4R keys of v ascending (R a power of two, at least 4).
template <int R>
GF_TARGET_AVX2_PATHS inline void bitonicSort4(__m256i* v) {
  for (int i = 0; i < R; i += 4) sortRegisters4(v + i);
  for (int size = 2; size <= R; size *= 2) {  // merge sorted runs of size / 2 registers
    for (int blk = 0; blk < R; blk += size) {
      for (int j = 0; j < size / 2; ++j) {
        __m256i a = v[blk + j], b = reverseLanes4(v[blk + size - 1 - j]);
        compareExchange4(&a, &b);
        v[blk + j] = a;
        v[blk + size - 1 - j] = reverseLanes4(b);
      }
    }
    halfCleanAndMerge4<R>(v, size / 4);
  }
}

/// The 8 lanes of an 8-bit mask's set bits, packed to the front (4 bits per lane).
struct CompressTable {
  std::uint32_t lanes[256];
  constexpr CompressTable() : lanes() {
    for (int m = 0; m < 256; ++m) {
      std::uint32_t v = 0;
      int o = 0;
      for (int b = 0; b < 8; ++b) {
        if (m & (1 << b)) v |= static_cast<std::uint32_t>(b) << (4 * o++);
      }
      lanes[m] = v;
    }
  }
};
constexpr CompressTable kCompress{};

/// The best K <= 4R keys, sorted, fed by a buffer of candidates within the threshold.
template <int R>
class TopKAvx2 {
 public:
  static constexpr int kSlots = 4 * R;

  void init(int k, float bound) {
    k_ = k;
    pending_ = 0;
    thr_ = bound;
    empty_ = true;
  }
  float threshold() const { return thr_; }

  GF_TARGET_AVX2_PATHS static float boxDist(const Node& nd, const float* q) {
    const __m128 q4 = _mm_load_ps(q);  // q[3] = 0, like the boxes' padding
    const __m128 lo = _mm_load_ps(nd.lo), hi = _mm_load_ps(nd.hi);
    const __m128 t =
        _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, q4), _mm_sub_ps(q4, hi)), _mm_setzero_ps());
    const __m128 t2 = simd::avx2::opaque(_mm_mul_ps(t, t));
    return (_mm_cvtss_f32(t2) + _mm_cvtss_f32(_mm_shuffle_ps(t2, t2, 1))) +
           _mm_cvtss_f32(_mm_shuffle_ps(t2, t2, 2));
  }

  GF_TARGET_AVX2_PATHS void scan(const Tree& t, const Node& nd, const float* q) {
    using simd::avx2::opaque;
    const std::uint32_t b = nd.begin;
    int m = static_cast<int>(nd.scan_end - b);
    const float *x = t.px.data() + b, *y = t.py.data() + b, *z = t.pz.data() + b;
    const std::uint32_t* ids = t.pidx.data() + b;
    if (nd.right == kSamePoint && !empty_) {
      const float dx = q[0] - x[0], dy = q[1] - y[0], dz = q[2] - z[0];
      const __m128 d2 =
          opaque(_mm_mul_ps(_mm_set_ps(0.f, dz, dy, dx), _mm_set_ps(0.f, dz, dy, dx)));
      const float d = (_mm_cvtss_f32(d2) + _mm_cvtss_f32(_mm_shuffle_ps(d2, d2, 1))) +
                      _mm_cvtss_f32(_mm_shuffle_ps(d2, d2, 2));
      const std::uint64_t kth = top_[k_ - 1];
      m = samePointPrefix(ids, m, d, kth == kNoKeyAvx2 ? kNoKey : kth);
    }
    const __m256 qx = _mm256_set1_ps(q[0]), qy = _mm256_set1_ps(q[1]), qz = _mm256_set1_ps(q[2]);
    const __m256i shifts = _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28);
    const __m256i nibble = _mm256_set1_epi32(0xf);
    int pending = pending_;  // in registers: see TopKAvx512::scan()
    __m256 thr = _mm256_set1_ps(thr_);
    for (int j = 0; j < m; j += 8) {
      __m256 px, py, pz;
      __m256i pi;
      int in = 0xff;
      if (m - j >= 8) {
        px = _mm256_loadu_ps(x + j);
        py = _mm256_loadu_ps(y + j);
        pz = _mm256_loadu_ps(z + j);
        pi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(ids + j));
      } else {  // the leaf's last block: masked loads (no read past the arrays)
        const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        const __m256i valid = _mm256_cmpgt_epi32(_mm256_set1_epi32(m - j), lane);
        px = _mm256_maskload_ps(x + j, valid);
        py = _mm256_maskload_ps(y + j, valid);
        pz = _mm256_maskload_ps(z + j, valid);
        pi = _mm256_maskload_epi32(reinterpret_cast<const int*>(ids + j), valid);
        in = (1 << (m - j)) - 1;
      }
      const __m256 dx = _mm256_sub_ps(qx, px), dy = _mm256_sub_ps(qy, py),
                   dz = _mm256_sub_ps(qz, pz);
      const __m256 d =
          _mm256_add_ps(_mm256_add_ps(opaque(_mm256_mul_ps(dx, dx)), opaque(_mm256_mul_ps(dy, dy))),
                        opaque(_mm256_mul_ps(dz, dz)));
      const int keep = _mm256_movemask_ps(_mm256_cmp_ps(d, thr, _CMP_LE_OQ)) & in;
      // No branch on `keep` (see TopKAvx512::scan()): compress through a permutation table.
      const __m256i perm = _mm256_and_si256(
          _mm256_srlv_epi32(_mm256_set1_epi32(static_cast<int>(kCompress.lanes[keep])), shifts),
          nibble);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(cand_d_ + pending),
                          _mm256_permutevar8x32_epi32(_mm256_castps_si256(d), perm));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(cand_i_ + pending),
                          _mm256_permutevar8x32_epi32(pi, perm));
      pending += __builtin_popcount(static_cast<unsigned>(keep));
      if (pending >= kSlots) {
        const int extra = pending - kSlots;
        pending_ = kSlots;
        flush();
        // Move the candidates past the flushed block to the front (extra < 8).
        _mm256_store_si256(reinterpret_cast<__m256i*>(cand_d_),
                           _mm256_load_si256(reinterpret_cast<const __m256i*>(cand_d_ + kSlots)));
        _mm256_store_si256(reinterpret_cast<__m256i*>(cand_i_),
                           _mm256_load_si256(reinterpret_cast<const __m256i*>(cand_i_ + kSlots)));
        pending = extra;
        thr = _mm256_set1_ps(thr_);
      }
    }
    pending_ = pending;
  }

  GF_TARGET_AVX2_PATHS void finish() {
    if (pending_ > 0 || empty_) flush();
  }
  bool complete() const { return top_[k_ - 1] != kNoKeyAvx2; }
  std::uint64_t key(int j) const { return top_[j] == kNoKeyAvx2 ? kNoKey : top_[j]; }

  GF_TARGET_AVX2_PATHS void write(std::int32_t* idx, float* dist) const {
    int j = 0;
    for (; j + 8 <= k_; j += 8) {
      const __m256 a = _mm256_load_ps(reinterpret_cast<const float*>(top_ + j));
      const __m256 b = _mm256_load_ps(reinterpret_cast<const float*>(top_ + j + 4));
      // Low halves (indices) and high halves (distance bits) of the 8 keys, in key order.
      const __m256i lo = _mm256_permute4x64_epi64(
          _mm256_castps_si256(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0))), 0xd8);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(idx + j), lo);
      if (dist) {
        const __m256i hi = _mm256_permute4x64_epi64(
            _mm256_castps_si256(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1))), 0xd8);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(dist + j), hi);
      }
    }
    for (; j < k_; ++j) {
      idx[j] = static_cast<std::int32_t>(static_cast<std::uint32_t>(top_[j]));
      if (dist) dist[j] = keyDist(top_[j]);
    }
  }

 private:
  /// Sorts the pending candidates and merges them into the top list.
  GF_TARGET_AVX2_PATHS void flush() {
    __m256i c[R];
    const __m256i none = _mm256_set1_epi64x(static_cast<long long>(kNoKeyAvx2));
    const __m256i count = _mm256_set1_epi64x(pending_);
    const int used = (pending_ + 3) / 4;
    for (int r = 0; r < R; ++r) {
      if (r >= used) {
        c[r] = none;
        continue;
      }
      const __m128i d = _mm_loadu_si128(reinterpret_cast<const __m128i*>(cand_d_ + 4 * r));
      const __m128i i = _mm_loadu_si128(reinterpret_cast<const __m128i*>(cand_i_ + 4 * r));
      const __m256i key = _mm256_or_si256(_mm256_slli_epi64(_mm256_cvtepu32_epi64(d), 32),
                                          _mm256_cvtepu32_epi64(i));
      const __m256i lane = _mm256_setr_epi64x(4 * r, 4 * r + 1, 4 * r + 2, 4 * r + 3);
      c[r] = _mm256_blendv_epi8(none, key, _mm256_cmpgt_epi64(count, lane));
    }
    // Registers past the candidates hold only empty slots: sort just the used ones.
    if (used <= 4) {
      bitonicSort4<4>(c);
    } else if (R >= 8 && used <= 8) {
      bitonicSort4<(R >= 8 ? 8 : 4)>(c);
    } else if (R >= 16 && used <= 16) {
      bitonicSort4<(R >= 16 ? 16 : 4)>(c);
    } else if (R >= 32 && used <= 32) {
      bitonicSort4<(R >= 32 ? 32 : 4)>(c);
    } else {
      bitonicSort4<R>(c);
    }
    if (empty_) {
      for (int r = 0; r < R; ++r) {
        _mm256_store_si256(reinterpret_cast<__m256i*>(top_ + 4 * r), c[r]);
      }
      empty_ = false;
    } else {
      // Smallest 4R of two sorted lists: min(top[i], c[4R-1-i]) is bitonic; merge it.
      __m256i t[R];
      for (int r = 0; r < R; ++r) {
        __m256i a = _mm256_load_si256(reinterpret_cast<const __m256i*>(top_ + 4 * r));
        __m256i b = reverseLanes4(c[R - 1 - r]);
        compareExchange4(&a, &b);
        t[r] = a;
      }
      halfCleanAndMerge4<R>(t, R / 2);
      for (int r = 0; r < R; ++r) {
        _mm256_store_si256(reinterpret_cast<__m256i*>(top_ + 4 * r), t[r]);
      }
    }
    pending_ = 0;
    const std::uint64_t kth = top_[k_ - 1];
    if (kth != kNoKeyAvx2) thr_ = std::min(thr_, keyDist(kth));
  }

  alignas(32) std::uint64_t top_[kSlots];
  alignas(32) std::uint32_t cand_d_[kSlots + 8];  // squared distance bits
  alignas(32) std::uint32_t cand_i_[kSlots + 8];  // point indices
  int k_ = 0, pending_ = 0;
  float thr_ = 0.f;
  bool empty_ = true;
};

GF_TARGET_AVX2_PATHS void queryRangeAvx2(const Tree& t, std::size_t pb, std::size_t pe, int k,
                                         std::int32_t* out_idx, float* out_dist) {
  if (k <= 16) {
    TopKAvx2<4> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 32) {
    TopKAvx2<8> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 64) {
    TopKAvx2<16> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 128) {
    TopKAvx2<32> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else {
    TopKAvx2<64> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  }
}

#pragma GCC diagnostic pop

bool cpuHasAvx2() { return simd::avx2::cpuHasAvx2(); }

#else

bool cpuHasAvx2() { return false; }

#endif  // GF_HAVE_AVX2_PATHS

void queryRangeScalar(const Tree& t, std::size_t pb, std::size_t pe, int k, std::int32_t* out_idx,
                      float* out_dist) {
  SortedKeys set;
  queryRange(t, pb, pe, k, &set, out_idx, out_dist);
}

/// Every pair (clouds smaller than K): rows of `found` sorted keys, then padding.
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

struct KdTreeNeighborSearch::Impl {
  KdTree tree;
  std::vector<std::int32_t> rows;  // kept lists: row p = tree position p, indices only
};

KdTreeNeighborSearch::KdTreeNeighborSearch(int threads, int leaf_size)
    : impl_(std::make_unique<Impl>()),
      threads_(threads > 0 ? threads : omp_get_num_procs()),
      leaf_size_(std::max(1, leaf_size)),
      use_avx512_(cpuHasAvx512()),
      has_avx2_(cpuHasAvx2()) {}

KdTreeNeighborSearch::~KdTreeNeighborSearch() = default;

void KdTreeNeighborSearch::setUseAvx512(bool use) { use_avx512_ = use && cpuHasAvx512(); }

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
  // Kept lists (searchWithPca() or searchWithCandidates() after keepListsOnDevice(true)): rows in
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

  const auto t1 = Clock::now();
  // Chunks of consecutive tree positions; each chunk's first query starts unbounded. With PCA,
  // each chunk's lists are used right after they are written, while they are in cache.
  constexpr std::size_t kChunk = 1024;
  const std::int64_t chunks = static_cast<std::int64_t>((n + kChunk - 1) / kChunk);
  const bool avx512 = use_avx512_ && kk <= kMaxAvx512K && simd::allows(simd::Level::kAvx512);
#if GF_HAVE_AVX2_PATHS
  const bool avx2 = !avx512 && has_avx2_ && kk <= kMaxAvx2K && simd::allows(simd::Level::kAvx2);
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
      queryRangeAvx512(im, pb, pe, static_cast<int>(kk), out_idx, out_dist);
    } else
#endif
#if GF_HAVE_AVX2_PATHS
        if (avx2) {
      queryRangeAvx2(im, pb, pe, static_cast<int>(kk), out_idx, out_dist);
    } else
#endif
    {
      queryRangeScalar(im, pb, pe, static_cast<int>(kk), out_idx, out_dist);
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

bool KdTreeNeighborSearch::keepListsOnDevice(bool keep) {
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
