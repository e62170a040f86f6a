#ifndef GROUND_FILTER_SRC_CORE_KNN_KDTREE_TREE_H
#define GROUND_FILTER_SRC_CORE_KNN_KDTREE_TREE_H

// Inside of KdTreeNeighborSearch, shared by its files: the tree (kdtree_build.cpp builds it), the
// sort keys, and the query loop every top-K set runs in (the sets: SortedKeys below,
// kdtree_query_avx512.cpp, kdtree_query_avx2.cpp). Private to knn/.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

#include "simd/avx2_common.h"
#include "simd/avx512_common.h"
#include "simd/neon_common.h"

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
//   starts with the guess (d_prev + |q - q_prev| / 2)^2, d_prev the previous query's K-th
//   distance: when K points lie within it, the list is exact; else it runs again with the bound
//   (d_prev + |q - q_prev|)^2, which holds the previous query's K neighbours, so the K-th
//   distance of q too. A query at the same coordinates as the previous one (a lidar's no-return
//   points at the origin) copies its list.
// - With AVX2 or AVX-512 the queries of one leaf share one descent: it lists the leaves within
//   reach of the leaf's box, and each query tests those boxes eight at a time instead of walking
//   the tree (queryRange()).
// - A neighbour list is ordered by the key (squared distance, index): the result is unique, so it
//   is the same for any thread count, traversal order or code path. Squared distances are
//   float ((dx*dx + dy*dy) + dz*dz), never fused multiply-adds, the same value as nanoflann's
//   L2_Simple_Adaptor and the tests' brute force.
// - With AVX-512 (checked at run time) candidates within the bound are computed 16 at a time and
//   kept in a buffer; full buffers are sorted by a bitonic network and merged into the sorted
//   top K (no per-candidate branches). With AVX2 only, the same scheme 8 distances at a time
//   (candidates packed by a permutation table) and 4 keys per register; with NEON (aarch64) 4
//   distances at a time and 2 keys per register. Otherwise a sorted array with insertion is used.
//   The SIMD level in force (simd.h, GF_SIMD) picks among them.

namespace ground_filter {
namespace kdtree {

constexpr std::uint64_t kNoKey = ~0ULL;  // an empty slot: larger than any real key

/// Sort key of a neighbour: squared distance bits (non-negative floats order like their bits),
/// then the point index.
inline std::uint64_t makeKey(float sq_dist, std::uint32_t idx) {
  std::uint32_t bits;
  std::memcpy(&bits, &sq_dist, sizeof bits);
  return (static_cast<std::uint64_t>(bits) << 32) | idx;
}

inline float keyDist(std::uint64_t key) {
  const std::uint32_t bits = static_cast<std::uint32_t>(key >> 32);
  float d;
  std::memcpy(&d, &bits, sizeof d);
  return d;
}

struct Point {
  float x, y, z;
  std::uint32_t idx;
};
static_assert(sizeof(Point) == 16, "the build moves points as 16-byte words (swapPoints())");

struct alignas(16) Node {
  float lo[4];  // tight bounding box of the node's points; [3] = 0
  float hi[4];
  std::uint32_t begin;     // first tree position of the node's points
  std::uint32_t scan_end;  // leaf: end of the positions to scan (see kSamePoint)
  std::int32_t left;       // children (left < 0: a leaf)
  std::int32_t right;      // leaf: 1 when all its points coincide (kSamePoint), else 0
};

constexpr std::int32_t kSamePoint = 1;

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
  std::vector<std::int32_t> leaf_node;    // node of the leaf at each tree position
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

using Tree = KdTree;

/// Squared distance from q to a node's box, summed like a point distance: never larger than the
/// (float) distance to any point inside the box.
inline float boxSqDist(const Node& nd, const float* q) {
  float d[3];
  for (int i = 0; i < 3; ++i) {
    d[i] = q[i] < nd.lo[i] ? nd.lo[i] - q[i] : (q[i] > nd.hi[i] ? q[i] - nd.hi[i] : 0.f);
  }
  return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

/// How many leading points of a same-point leaf (indices ascending, all at squared distance d)
/// can still enter a list whose K-th key is `kth` (kNoKey while the list is not full).
inline int samePointPrefix(const std::uint32_t* ids, int m, float d, std::uint64_t kth) {
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

/// Squared distance between two nodes' boxes, summed like boxSqDist(): never larger than the
/// (float) distance from a point in one box to a point in the other.
inline float boxBoxSqDist(const Node& a, const Node& b) {
  float d[3];
  for (int i = 0; i < 3; ++i) {
    d[i] = a.lo[i] > b.hi[i] ? a.lo[i] - b.hi[i] : (b.lo[i] > a.hi[i] ? b.lo[i] - a.hi[i] : 0.f);
  }
  return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

/// Most leaves on a group's list (queryRange()); a group that reaches more descends per query.
constexpr int kMaxGroupLeaves = 256;

/// Share of the step from the query before a group to its farthest point that the reach of the
/// group's list adds to that query's K-th distance (queryRange()). Only the time depends on it:
/// KITTI 000000 and the OS-128 scan, AVX2, 2 threads, the search 15-20 % and 8-12 % faster than
/// one descent a query at 0.1-0.25 (0.15 the best of both), less at 0.5; at 0.15 about 5 % of a
/// KITTI frame's queries find fewer than K points on the list and descend.
constexpr double kGroupShare = 0.15;

/// A group's leaves: node ids and boxes, the boxes' coordinates in separate arrays padded to a
/// multiple of 8 with empty boxes (lo = hi = +inf; scanLeaves() masks them out).
struct LeafList {
  int count = -1;  // -1: no list (more than kMaxGroupLeaves leaves)
  alignas(32) float lx[kMaxGroupLeaves + 8], ly[kMaxGroupLeaves + 8], lz[kMaxGroupLeaves + 8];
  alignas(32) float hx[kMaxGroupLeaves + 8], hy[kMaxGroupLeaves + 8], hz[kMaxGroupLeaves + 8];
  std::int32_t id[kMaxGroupLeaves + 8];
};

/// The leaves whose boxes lie within sqrt(rsq) of `box`, in tree order, into `out`.
inline void collectLeaves(const Tree& t, const Node& box, float rsq, LeafList* out) {
  std::int32_t stack[128];  // two a level
  int sp = 0, count = 0;
  stack[sp++] = 0;
  while (sp > 0) {
    const Node& nd = t.nodes[static_cast<std::size_t>(stack[--sp])];
    // 1e-6 short: the box sums may round otherwise than a point's (fused multiply-adds).
    if (boxBoxSqDist(nd, box) * 0.999999f > rsq) continue;
    if (nd.left >= 0) {
      stack[sp++] = nd.right;
      stack[sp++] = nd.left;
      continue;
    }
    if (count == kMaxGroupLeaves) {
      out->count = -1;
      return;
    }
    out->id[count] = static_cast<std::int32_t>(&nd - t.nodes.data());
    out->lx[count] = nd.lo[0];
    out->ly[count] = nd.lo[1];
    out->lz[count] = nd.lo[2];
    out->hx[count] = nd.hi[0];
    out->hy[count] = nd.hi[1];
    out->hz[count] = nd.hi[2];
    ++count;
  }
  out->count = count;
  const float inf = std::numeric_limits<float>::infinity();
  for (int i = count; i < (count + 7) / 8 * 8; ++i) {
    out->lx[i] = out->ly[i] = out->lz[i] = out->hx[i] = out->hy[i] = out->hz[i] = inf;
    out->id[i] = 0;
  }
}

/// Whether a top-K set runs on AVX2 or above (a member kSearchesByGroups = true): then
/// queryRange() searches by groups (the portable and NEON sets descend per query).
template <class S, class = void>
struct SearchesByGroups : std::false_type {};
template <class S>
struct SearchesByGroups<S, std::void_t<decltype(S::kSearchesByGroups)>>
    : std::bool_constant<S::kSearchesByGroups> {};

#if GF_HAVE_AVX2_PATHS
/// Per lane, how far x lies outside [lo, hi] (0 inside).
GF_TARGET_AVX2_PATHS inline __m256 boxGap8(const float* lo, const float* hi, __m256 x) {
  return _mm256_max_ps(
      _mm256_max_ps(_mm256_sub_ps(_mm256_load_ps(lo), x), _mm256_sub_ps(x, _mm256_load_ps(hi))),
      _mm256_setzero_ps());
}

/// Scans the leaves of a list whose boxes lie within the set's threshold of q, in list order,
/// eight boxes a step (distances summed like a point's).
template <class Set>
GF_TARGET_AVX2_PATHS inline void scanLeaves(const Tree& t, const LeafList& list, const float* q,
                                            Set* set) {
  using simd::avx2::opaque;
  const __m256 qx = _mm256_set1_ps(q[0]), qy = _mm256_set1_ps(q[1]), qz = _mm256_set1_ps(q[2]);
  for (int i = 0; i < list.count; i += 8) {
    const __m256 dx = boxGap8(list.lx + i, list.hx + i, qx),
                 dy = boxGap8(list.ly + i, list.hy + i, qy),
                 dz = boxGap8(list.lz + i, list.hz + i, qz);
    const __m256 d =
        _mm256_add_ps(_mm256_add_ps(opaque(_mm256_mul_ps(dx, dx)), opaque(_mm256_mul_ps(dy, dy))),
                      opaque(_mm256_mul_ps(dz, dz)));
    unsigned in = static_cast<unsigned>(
        _mm256_movemask_ps(_mm256_cmp_ps(d, _mm256_set1_ps(set->threshold()), _CMP_LE_OQ)));
    if (list.count - i < 8) in &= (1u << (list.count - i)) - 1;  // not the padding (+inf bounds)
    while (in) {
      const int j = __builtin_ctz(in);
      in &= in - 1;
      set->scan(t, t.nodes[static_cast<std::size_t>(list.id[i + j])], q);
    }
  }
  set->finish();
}
#endif

/// r^2 as a float bound on squared distances, a little over: the margin covers the float
/// rounding of the distances (a few ulp); a bound that is too small anyway is caught by the
/// query's completeness check.
inline float squaredBound(double r) { return static_cast<float>(r * r * (1.0 + 1e-5) + 1e-30); }

/// Share of the step from the previous query that the first, guessed bound of a query adds to
/// the previous K-th distance (the guaranteed bound adds all of it). Only the time depends on it:
/// KITTI frames, one thread, AVX2, the search 10-15 % faster at 0.5-0.8 than with the guaranteed
/// bound alone, slower at 0 (half the guesses miss); 2.4 % of the guesses miss at 0.5.
constexpr double kGuessShare = 0.5;

/// Queries the points at tree positions [pb, pe) in order, each bounded by the previous one.
/// Row of the point at tree position p: its point index (input order), or p itself when
/// `out_dist` is null (the kept layout: indices only, written sequentially).
///
/// SIMD sets (SearchesByGroups) search by groups: the queries of one leaf share a list of the
/// leaves within reach of its box, reach = d_ref + kGroupShare * (the farthest of them from
/// ref), ref the query before the group and d_ref its K-th distance; one descent a group
/// instead of one a query. A query scans the list with its guess, cut to the reach: K points
/// within that make its list exact (every point within it lies on the list's leaves); fewer,
/// and it descends with its guaranteed bound.
template <class Set>
GF_KNN_ALWAYS_INLINE void queryRange(const Tree& t, std::size_t pb, std::size_t pe, int k, Set* set,
                                     std::int32_t* out_idx, float* out_dist) {
  const float inf = std::numeric_limits<float>::infinity();
  const std::size_t kk = static_cast<std::size_t>(k);
  float prev[3] = {0.f, 0.f, 0.f};
  double prev_kth = -1.0;
  std::size_t prev_row = 0;
#if GF_HAVE_AVX2_PATHS
  LeafList list;
  std::int32_t group_leaf = -1;
  float reach = 0.f;  // the list's reach, squared
#endif
  for (std::size_t p = pb; p < pe; ++p) {
    alignas(16) const float q[4] = {t.px[p], t.py[p], t.pz[p], 0.f};
    const std::size_t row = (out_dist ? static_cast<std::size_t>(t.pidx[p]) : p) * kk;
    if (prev_kth >= 0.0 && q[0] == prev[0] && q[1] == prev[1] && q[2] == prev[2]) {
      // The same point again (e.g. a lidar's no-return points at the origin): same list.
      std::copy_n(out_idx + prev_row, kk, out_idx + row);
      if (out_dist) std::copy_n(out_dist + prev_row, kk, out_dist + row);
      continue;
    }
    float bound = inf, guess = inf;
    if (prev_kth >= 0.0) {
      const double dx = static_cast<double>(q[0]) - prev[0],
                   dy = static_cast<double>(q[1]) - prev[1],
                   dz = static_cast<double>(q[2]) - prev[2];
      const double d_prev = std::sqrt(prev_kth), step = std::sqrt(dx * dx + dy * dy + dz * dz);
      bound = squaredBound(d_prev + step);
      guess = squaredBound(d_prev + kGuessShare * step);
    }
    bool done = false;
#if GF_HAVE_AVX2_PATHS
    if constexpr (SearchesByGroups<Set>::value) {
      if (prev_kth >= 0.0 && t.leaf_node[p] != group_leaf) {  // a new group: its list
        group_leaf = t.leaf_node[p];
        double far = 0.0;  // the farthest of the group's points from the query before it
        for (std::size_t g = p; g < pe && t.leaf_node[g] == group_leaf; ++g) {
          const double dx = static_cast<double>(t.px[g]) - prev[0],
                       dy = static_cast<double>(t.py[g]) - prev[1],
                       dz = static_cast<double>(t.pz[g]) - prev[2];
          far = std::max(far, dx * dx + dy * dy + dz * dz);
        }
        reach = squaredBound(std::sqrt(prev_kth) + kGroupShare * std::sqrt(far));
        collectLeaves(t, t.nodes[static_cast<std::size_t>(group_leaf)], reach, &list);
      }
      if (prev_kth >= 0.0 && list.count >= 0) {
        set->init(k, std::min(guess, reach));
        scanLeaves(t, list, q, set);
        if (!set->complete()) guess = bound;  // then one descent with the bound
        done = set->complete();
      }
    }
#endif
    // First the guess: K points within it make the list exact (the K nearest lie no farther
    // than the K-th of them); fewer (2 % of a KITTI frame's queries), then the bound.
    if (!done) {
      set->init(k, guess);
      descend(t, q, set);
      if (!set->complete() && guess < bound) {
        set->init(k, bound);
        descend(t, q, set);
      }
    }
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

/// Largest K of the AVX2 code (64 registers of keys); larger K use the portable code.
constexpr std::size_t kMaxAvx2K = 256;

/// One top-K set per query range (chunk of tree positions [pb, pe)): the K nearest neighbours of
/// each point there into `out_idx` / `out_dist` rows (rows in input order; `out_dist` null = kept
/// rows in tree order, indices only). The portable set; the SIMD ones where built and allowed.
void queryRangeScalar(const Tree& t, std::size_t pb, std::size_t pe, int k, std::int32_t* out_idx,
                      float* out_dist);
#if GF_HAVE_AVX512
GF_TARGET_AVX512 void queryRangeAvx512(const Tree& t, std::size_t pb, std::size_t pe, int k,
                                       std::int32_t* out_idx, float* out_dist);
#endif
#if GF_HAVE_AVX2_PATHS
GF_TARGET_AVX2_PATHS void queryRangeAvx2(const Tree& t, std::size_t pb, std::size_t pe, int k,
                                         std::int32_t* out_idx, float* out_dist);
#endif
/// Largest K of the NEON code (128 registers of keys); larger K use the portable code.
constexpr std::size_t kMaxNeonK = 256;
#if GF_HAVE_NEON_PATHS
void queryRangeNeon(const Tree& t, std::size_t pb, std::size_t pe, int k, std::int32_t* out_idx,
                    float* out_dist);
#endif
/// Whether this CPU (and build) runs the AVX-512 / AVX2 query code.
bool cpuHasAvx512();
bool cpuHasAvx2();

}  // namespace kdtree
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_KNN_KDTREE_TREE_H
