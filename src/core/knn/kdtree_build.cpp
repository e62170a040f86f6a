// KdTreeNeighborSearch: the tree build (median splits, parallel subtrees).

#include <omp.h>
#if defined(__SSE__)
#include <xmmintrin.h>
#elif defined(__aarch64__) && defined(__ARM_NEON)
#include <arm_neon.h>
#endif

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <vector>

#include "knn/kdtree_tree.h"

namespace ground_filter {
namespace kdtree {

namespace {

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

/// Swaps two points as whole 16-byte words: the next load of *b reads what this stored as one
/// piece (a copy field by field stalls that load until the pieces are written).
inline void swapPoints(Point* a, Point* b) {
#if defined(__SSE__)
  const __m128 va = _mm_loadu_ps(&a->x), vb = _mm_loadu_ps(&b->x);
  _mm_storeu_ps(&a->x, vb);
  _mm_storeu_ps(&b->x, va);
#elif defined(__aarch64__) && defined(__ARM_NEON)
  float32x4_t va, vb;  // memcpy: the index's bits move through a float register untouched
  std::memcpy(&va, a, sizeof va);
  std::memcpy(&vb, b, sizeof vb);
  std::memcpy(a, &vb, sizeof vb);
  std::memcpy(b, &va, sizeof va);
#else
  std::swap(*a, *b);
#endif
}

template <int D>
inline float axisKey(const Point& p) {
  return D == 0 ? p.x : (D == 1 ? p.y : p.z);
}

/// Nodes of fewer points than this select their median with selectMedian()'s quickselect,
/// larger ones with std::nth_element. On a KITTI frame's sampled points (62 k, in column order)
/// std::nth_element took 0.11-0.15 ms for each of the top three levels of the tree but
/// 0.36-0.66 ms for each of the levels of 250-1000 points, where its partitions mispredict
/// about every other point; the quickselect took 0.11-0.23 ms a level below 8 k points. Whole
/// selection on one thread, KITTI 000000 / 000003: 1.39 / 1.39 ms with this switch, 1.31 / 1.33
/// at 8 k, 1.28 / 1.76 at 16 k; on 000000 3.1 with std::nth_element alone, 1.65 with the
/// quickselect everywhere.
constexpr std::ptrdiff_t kQuickselectMaxPoints = 4096;

/// std::nth_element(first, mid, last) by the axis D key, with the same guarantee (nothing
/// before mid above it, nothing after it below it); below kQuickselectMaxPoints a quickselect
/// whose partition does not branch on the keys. A pivot that is the part's least key (many
/// equal keys) is followed by a pass that moves its equals next to it.
template <int D>
void selectMedian(Point* first, Point* mid, Point* last) {
  const auto less = [](const Point& a, const Point& b) { return axisKey<D>(a) < axisKey<D>(b); };
  if (last - first >= kQuickselectMaxPoints) {
    std::nth_element(first, mid, last, less);
    return;
  }
  for (int round = 0; last - first > 16; ++round) {
    if (round == 64) break;  // a bound on the cost whatever the keys: leave it to the library
    // The pivot: of the keys at 1/6, 3/6 and 5/6 of the part, sorted, the one whose rank
    // matches mid's (the middle one on the first round; after it mid lies near an end of its
    // part, and a pivot near that end leaves a small part). First, middle and last keys instead
    // (the points come in column order): 1.82 against 1.43 ms a KITTI frame's selection.
    const std::ptrdiff_t n = last - first;
    Point* sp[3] = {first + n / 6, first + n / 2, first + 5 * n / 6};
    if (less(*sp[1], *sp[0])) std::swap(sp[0], sp[1]);
    if (less(*sp[2], *sp[1])) std::swap(sp[1], sp[2]);
    if (less(*sp[1], *sp[0])) std::swap(sp[0], sp[1]);
    std::swap(*first, *sp[(mid - first) * 3 / n]);
    const float pivot = axisKey<D>(*first);
    // Lomuto without branches: [first + 1, w) below the pivot, [w, r) not.
    Point* w = first + 1;
    for (Point* r = first + 1; r < last; ++r) {
      const bool below = axisKey<D>(*r) < pivot;
      swapPoints(r, w);
      w += below;
    }
    Point* const p = w - 1;  // the pivot's place
    std::swap(*first, *p);
    if (mid == p) return;
    if (mid < p) {
      last = p;
      continue;
    }
    if (p == first) {  // nothing below the pivot: its equals next to it, then the rest
      Point* e = p + 1;
      for (Point* r = p + 1; r < last; ++r) {
        const bool equal = !(pivot < axisKey<D>(*r));
        swapPoints(r, e);
        e += equal;
      }
      if (mid < e) return;
      first = e;
      continue;
    }
    first = p + 1;
  }
  std::nth_element(first, mid, last, less);
}

}  // namespace

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
    for (std::uint32_t i = b; i < e; ++i) {
      leaf_of[pts[i].idx] = b;
      leaf_node[i] = static_cast<std::int32_t>(id);
    }
    cursor[b] = b;
    cursor_end[b] = e;
    if (same_point) {
      nd.scan_end = std::min<std::uint32_t>(e, b + static_cast<std::uint32_t>(k));
      nd.right = kSamePoint;
    }
    return;
  }
  const std::uint32_t m = b + (e - b) / 2;
  // One selection per axis: a fixed offset instead of an indexed load in the inner loops.
  Point* const first = pts.data() + b;
  Point* const mid = pts.data() + m;
  Point* const last = pts.data() + e;
  if (dim == 0) {
    selectMedian<0>(first, mid, last);
  } else if (dim == 1) {
    selectMedian<1>(first, mid, last);
  } else {
    selectMedian<2>(first, mid, last);
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
  leaf_node.resize(n);
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

}  // namespace kdtree
}  // namespace ground_filter
