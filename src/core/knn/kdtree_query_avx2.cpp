// KdTreeNeighborSearch: the AVX2 top-K set (4 keys per register, candidates packed by a permutation
// table).

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <utility>

#include "knn/kdtree_tree.h"
#include "simd/avx2_common.h"
#include "simd/avx512_common.h"
#include "simd/simd.h"

namespace ground_filter {
namespace kdtree {

#if GF_HAVE_AVX2_PATHS

// AVX2 (no AVX-512): the same scheme as TopKAvx512, four 64-bit keys per register. AVX2 has no
// unsigned 64-bit min/max: keys are compared as signed (a key's distance bits are those of a
// non-negative float, so real keys are below 2^63) and an empty slot is INT64_MAX instead of
// kNoKey.

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

namespace {  // the set and its helpers; only the entry point below is shared

constexpr std::uint64_t kNoKeyAvx2 = 0x7fffffffffffffffULL;

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

/// Squared distance from q (4 floats, q[3] = 0) to a node's box.
GF_TARGET_AVX2_PATHS inline float boxDistAvx2(const Node& nd, const float* q) {
  const __m128 q4 = _mm_load_ps(q);  // q[3] = 0, like the boxes' padding
  const __m128 lo = _mm_load_ps(nd.lo), hi = _mm_load_ps(nd.hi);
  const __m128 t = _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, q4), _mm_sub_ps(q4, hi)), _mm_setzero_ps());
  const __m128 t2 = simd::avx2::opaque(_mm_mul_ps(t, t));
  return (_mm_cvtss_f32(t2) + _mm_cvtss_f32(_mm_shuffle_ps(t2, t2, 1))) +
         _mm_cvtss_f32(_mm_shuffle_ps(t2, t2, 2));
}

/// Squared distance from q to the leaf's first point (a same-point leaf: all of its points).
GF_TARGET_AVX2_PATHS inline float firstPointDist(const Tree& t, const Node& nd, const float* q) {
  const std::uint32_t b = nd.begin;
  const float dx = q[0] - t.px[b], dy = q[1] - t.py[b], dz = q[2] - t.pz[b];
  const __m128 d2 =
      simd::avx2::opaque(_mm_mul_ps(_mm_set_ps(0.f, dz, dy, dx), _mm_set_ps(0.f, dz, dy, dx)));
  return (_mm_cvtss_f32(d2) + _mm_cvtss_f32(_mm_shuffle_ps(d2, d2, 1))) +
         _mm_cvtss_f32(_mm_shuffle_ps(d2, d2, 2));
}

/// Appends the first m points of a leaf that lie within `thr` of q to the candidates (distance
/// bits in cd, index in ci) from position n on, eight at a time. Once more than `limit` are
/// held, `set->makeRoom(n)` makes room and returns the count left and the new threshold. Returns
/// the count. No branch on which points pass (see TopKAvx512::scan()): they are packed through a
/// permutation table, and each step writes 8 lanes at n (limit + 8 slots needed).
template <class Set>
GF_TARGET_AVX2_PATHS inline int packLeafAvx2(const Tree& t, const Node& nd, int m, const float* q,
                                             float thr_in, int limit, std::uint32_t* cd,
                                             std::uint32_t* ci, int n, Set* set) {
  using simd::avx2::opaque;
  const std::uint32_t b = nd.begin;
  const float *x = t.px.data() + b, *y = t.py.data() + b, *z = t.pz.data() + b;
  const std::uint32_t* ids = t.pidx.data() + b;
  const __m256 qx = _mm256_set1_ps(q[0]), qy = _mm256_set1_ps(q[1]), qz = _mm256_set1_ps(q[2]);
  __m256 thr = _mm256_set1_ps(thr_in);
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
    const __m256 dx = _mm256_sub_ps(qx, px), dy = _mm256_sub_ps(qy, py), dz = _mm256_sub_ps(qz, pz);
    const __m256 d =
        _mm256_add_ps(_mm256_add_ps(opaque(_mm256_mul_ps(dx, dx)), opaque(_mm256_mul_ps(dy, dy))),
                      opaque(_mm256_mul_ps(dz, dz)));
    const int keep = _mm256_movemask_ps(_mm256_cmp_ps(d, thr, _CMP_LE_OQ)) & in;
    const __m256i perm = simd::avx2::compressPermutation(keep);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(cd + n),
                        _mm256_permutevar8x32_epi32(_mm256_castps_si256(d), perm));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(ci + n), _mm256_permutevar8x32_epi32(pi, perm));
    n += __builtin_popcount(static_cast<unsigned>(keep));
    if (n > limit) {
      const std::pair<int, float> left = set->makeRoom(n);
      n = left.first;
      thr = _mm256_set1_ps(left.second);
    }
  }
  return n;
}

/// The best K <= 4R keys, sorted, fed by a buffer of candidates within the threshold.
template <int R>
class TopKAvx2 {
 public:
  static constexpr bool kSearchesByGroups = true;  // in queryRange() (AVX2 box tests)
  static constexpr int kSlots = 4 * R;

  void init(int k, float bound) {
    k_ = k;
    pending_ = 0;
    thr_ = bound;
    empty_ = true;
  }
  float threshold() const { return thr_; }

  GF_TARGET_AVX2_PATHS static float boxDist(const Node& nd, const float* q) {
    return boxDistAvx2(nd, q);
  }

  GF_TARGET_AVX2_PATHS void scan(const Tree& t, const Node& nd, const float* q) {
    int m = static_cast<int>(nd.scan_end - nd.begin);
    if (nd.right == kSamePoint && !empty_) {
      const std::uint64_t kth = top_[k_ - 1];
      m = samePointPrefix(t.pidx.data() + nd.begin, m, firstPointDist(t, nd, q),
                          kth == kNoKeyAvx2 ? kNoKey : kth);
    }
    // The count in a register, not pending_ (see TopKAvx512::scan()).
    pending_ = packLeafAvx2(t, nd, m, q, thr_, kSlots - 1, cand_d_, cand_i_, pending_, this);
  }

  /// Flushes a full buffer of `pending` candidates (kSlots up to kSlots + 7): the count left
  /// and the new threshold (packLeafAvx2()).
  GF_TARGET_AVX2_PATHS std::pair<int, float> makeRoom(int pending) {
    const int extra = pending - kSlots;
    pending_ = kSlots;
    flush();
    // Move the candidates past the flushed block to the front (extra < 8).
    _mm256_store_si256(reinterpret_cast<__m256i*>(cand_d_),
                       _mm256_load_si256(reinterpret_cast<const __m256i*>(cand_d_ + kSlots)));
    _mm256_store_si256(reinterpret_cast<__m256i*>(cand_i_),
                       _mm256_load_si256(reinterpret_cast<const __m256i*>(cand_i_ + kSlots)));
    return std::make_pair(extra, thr_);
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

// ---- K of 33-64 (the normal method's default 40): a buffer of 32-bit sort proxies ----------
//
// TopKAvx2<16> keeps 64 keys of 64 bits in 16 registers, all that AVX2 has, and its flush
// spills them. A query of the normal method passes about 58 candidates in all (KITTI, the
// guessed bound of queryRange()), so this set keeps every candidate in one buffer of 128 and
// sorts it once at the end (earlier only when the buffer fills). The sort runs on 32-bit
// proxies: the distance bits with the low 8 cleared, the candidate's slot in the low 8; 64 of
// them fit in 8 registers. Proxies order the candidates as their (distance, index) keys do
// except where two distances share all but their low 8 bits (2^-15 apart): such a run among
// the first K + 1 is put in the order of the full keys (sortTiedRuns()).

constexpr int kProxyBits = 8;                                // slots < 256
constexpr std::uint32_t kSlotMask = (1u << kProxyBits) - 1;  // a proxy's slot bits
constexpr std::uint32_t kProxyPad = 0xffffffffu;  // above any real proxy (distances <= +inf)

GF_TARGET_AVX2_PATHS inline void minMax8(__m256i* a, __m256i* b) {
  const __m256i lo = _mm256_min_epu32(*a, *b);
  *b = _mm256_max_epu32(*a, *b);
  *a = lo;
}

/// Sorts the 8 lanes of a register that form a bitonic sequence.
GF_TARGET_AVX2_PATHS inline __m256i laneMerge8(__m256i v) {
  __m256i p = _mm256_permute2x128_si256(v, v, 0x01);  // lanes 4-7 0-3
  v = _mm256_blend_epi32(_mm256_min_epu32(v, p), _mm256_max_epu32(v, p), 0xf0);
  p = _mm256_shuffle_epi32(v, 0x4e);  // lanes 2 3 0 1 in each half
  v = _mm256_blend_epi32(_mm256_min_epu32(v, p), _mm256_max_epu32(v, p), 0xcc);
  p = _mm256_shuffle_epi32(v, 0xb1);  // lanes 1 0 3 2 in each half
  return _mm256_blend_epi32(_mm256_min_epu32(v, p), _mm256_max_epu32(v, p), 0xaa);
}

/// Sorts each of 8 registers: an 8-input sorting network across them (19 comparators), then
/// an 8 x 8 transpose.
GF_TARGET_AVX2_PATHS inline void sortRegisters8(__m256i* v) {
  static constexpr int kNet[19][2] = {{0, 2}, {1, 3}, {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6},
                                      {3, 7}, {0, 1}, {2, 3}, {4, 5}, {6, 7}, {2, 4}, {3, 5},
                                      {1, 4}, {3, 6}, {1, 2}, {3, 4}, {5, 6}};
#pragma GCC unroll 19
  for (const auto& c : kNet) minMax8(&v[c[0]], &v[c[1]]);
  __m256i t[8], u[8];
#pragma GCC unroll 4
  for (int i = 0; i < 8; i += 2) {
    t[i] = _mm256_unpacklo_epi32(v[i], v[i + 1]);
    t[i + 1] = _mm256_unpackhi_epi32(v[i], v[i + 1]);
  }
#pragma GCC unroll 2
  for (int i = 0; i < 8; i += 4) {
    u[i] = _mm256_unpacklo_epi64(t[i], t[i + 2]);
    u[i + 1] = _mm256_unpackhi_epi64(t[i], t[i + 2]);
    u[i + 2] = _mm256_unpacklo_epi64(t[i + 1], t[i + 3]);
    u[i + 3] = _mm256_unpackhi_epi64(t[i + 1], t[i + 3]);
  }
#pragma GCC unroll 4
  for (int i = 0; i < 4; ++i) {
    v[i] = _mm256_permute2x128_si256(u[i], u[i + 4], 0x20);
    v[i + 4] = _mm256_permute2x128_si256(u[i], u[i + 4], 0x31);
  }
}

/// Half-cleaners over registers S, S / 2, ..., 1 apart (S = 0: none).
template <int R, int S>
GF_TARGET_AVX2_PATHS inline void halfClean8(__m256i* v) {
  if constexpr (S >= 1) {
#pragma GCC unroll 16
    for (int i = 0; i < R; ++i) {
      if (!(i & S)) minMax8(&v[i], &v[i + S]);
    }
    halfClean8<R, S / 2>(v);
  }
}

/// Merges the sorted runs of Size / 2 registers into runs of Size, then the next level up to R.
/// Templates all the way down, so that every index is a constant and v stays in registers.
template <int R, int Size>
GF_TARGET_AVX2_PATHS inline void mergeRuns8(__m256i* v) {
  const __m256i rev = _mm256_setr_epi32(7, 6, 5, 4, 3, 2, 1, 0);
#pragma GCC unroll 16
  for (int blk = 0; blk < R; blk += Size) {
    __m256i hi[Size / 2];
#pragma GCC unroll 8
    for (int j = 0; j < Size / 2; ++j) {
      // The run's second half reversed against its first: both halves become bitonic.
      __m256i b = _mm256_permutevar8x32_epi32(v[blk + Size - 1 - j], rev);
      minMax8(&v[blk + j], &b);
      hi[j] = b;
    }
#pragma GCC unroll 8
    for (int j = 0; j < Size / 2; ++j) v[blk + Size / 2 + j] = hi[j];
  }
  halfClean8<R, Size / 4>(v);
#pragma GCC unroll 16
  for (int i = 0; i < R; ++i) v[i] = laneMerge8(v[i]);
  if constexpr (2 * Size <= R) mergeRuns8<R, 2 * Size>(v);
}

/// Sorts the 8R proxies of v ascending (R = 8 or 16).
template <int R>
GF_TARGET_AVX2_PATHS inline void bitonicSort8(__m256i* v) {
#pragma GCC unroll 2
  for (int i = 0; i < R; i += 8) sortRegisters8(v + i);
  mergeRuns8<R, 2>(v);
}

/// The proxies of the first n candidates (distance bits d[j], slot j) sorted into sp[0, 8R),
/// padding after them and in sp[8R, 8R + 8).
template <int R>
GF_TARGET_AVX2_PATHS inline void sortProxies(const std::uint32_t* d, int n, std::uint32_t* sp) {
  __m256i v[R];
  const __m256i low = _mm256_set1_epi32(static_cast<int>(kSlotMask));
  const __m256i pad = _mm256_set1_epi32(static_cast<int>(kProxyPad));
  const __m256i count = _mm256_set1_epi32(n);
#pragma GCC unroll 16
  for (int r = 0; r < R; ++r) {
    const __m256i lane = _mm256_setr_epi32(8 * r, 8 * r + 1, 8 * r + 2, 8 * r + 3, 8 * r + 4,
                                           8 * r + 5, 8 * r + 6, 8 * r + 7);
    // Lanes at or past n (within the buffer, not yet written) become padding.
    const __m256i dr = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(d + 8 * r));
    const __m256i proxy = _mm256_or_si256(_mm256_andnot_si256(low, dr), lane);
    v[r] = _mm256_blendv_epi8(pad, proxy, _mm256_cmpgt_epi32(count, lane));
  }
  bitonicSort8<R>(v);
#pragma GCC unroll 16
  for (int r = 0; r < R; ++r) _mm256_store_si256(reinterpret_cast<__m256i*>(sp + 8 * r), v[r]);
  _mm256_store_si256(reinterpret_cast<__m256i*>(sp + 8 * R), pad);
}

/// The best K (33-64) keys of the candidates within the threshold, sorted; every candidate in
/// one buffer, sorted when it fills and at the end (see above).
class TopKProxyAvx2 {
 public:
  static constexpr bool kSearchesByGroups = true;  // in queryRange() (AVX2 box tests)
  static constexpr int kBuf = 128;                 // candidates sorted at once
  static constexpr int kFill = kBuf - 8;  // sort when more than this (a block adds up to 8)

  void init(int k, float bound) {
    k_ = k;
    n_ = 0;
    kept_ = 0;
    thr_ = bound;
    ordered_ = false;
  }
  float threshold() const { return thr_; }

  GF_TARGET_AVX2_PATHS static float boxDist(const Node& nd, const float* q) {
    return boxDistAvx2(nd, q);
  }

  GF_TARGET_AVX2_PATHS void scan(const Tree& t, const Node& nd, const float* q) {
    int m = static_cast<int>(nd.scan_end - nd.begin);
    if (nd.right == kSamePoint && kept_ == k_) {
      m = samePointPrefix(t.pidx.data() + nd.begin, m, firstPointDist(t, nd, q), key(k_ - 1));
    }
    n_ = packLeafAvx2(t, nd, m, q, thr_, kFill, d_, i_, n_, this);
  }

  /// Sorts a full buffer of n candidates: the count left and the new threshold (packLeafAvx2()).
  GF_TARGET_AVX2_PATHS std::pair<int, float> makeRoom(int n) {
    n_ = n;
    reduce();
    return std::make_pair(n_, thr_);
  }

  /// The query's last sort: the best K stay where they are, in the order of order_ (write()
  /// reads them through it: no copy to the front).
  GF_TARGET_AVX2_PATHS void finish() {
    if (n_ > kept_) reduce(true);  // candidates not sorted yet (none at all: nothing to keep)
  }
  bool complete() const { return kept_ == k_; }
  std::uint64_t key(int j) const {
    if (j >= kept_) return kNoKey;
    const int s = ordered_ ? static_cast<int>(order_[j] & kSlotMask) : j;
    return (static_cast<std::uint64_t>(d_[s]) << 32) | i_[s];
  }

  void write(std::int32_t* idx, float* dist) const {
    if (ordered_) {
      for (int j = 0; j < kept_; ++j) {
        const std::uint32_t s = order_[j] & kSlotMask;
        idx[j] = static_cast<std::int32_t>(i_[s]);
        if (dist) std::memcpy(dist + j, d_ + s, sizeof(float));
      }
    } else {
      std::memcpy(idx, i_, static_cast<std::size_t>(kept_) * sizeof(std::int32_t));
      if (dist) std::memcpy(dist, d_, static_cast<std::size_t>(kept_) * sizeof(float));
    }
    for (int j = kept_; j < k_; ++j) {  // fewer points than K: TopKAvx2's empty slots
      idx[j] = -1;
      if (dist) {
        const std::uint32_t none = 0x7fffffffu;
        std::memcpy(dist + j, &none, sizeof none);
      }
    }
  }

 private:
  std::uint64_t slotKey(std::uint32_t proxy) const {
    const std::uint32_t s = proxy & kSlotMask;
    return (static_cast<std::uint64_t>(d_[s]) << 32) | i_[s];
  }

  /// Puts each run of sorted proxies with equal upper bits that starts before `keep` in the
  /// order of the full keys (distance, index): the runs are contiguous, and everything before
  /// a run is smaller and everything after it larger, so the first `keep` are then exact.
  void sortTiedRuns(std::uint32_t* sp, int n, int keep) const {
    for (int j = 0; j < keep;) {
      int e = j + 1;
      while (e < n && (sp[e] >> kProxyBits) == (sp[j] >> kProxyBits)) ++e;
      for (int a = j + 1; a < e; ++a) {  // insertion sort: runs are short
        const std::uint32_t v = sp[a];
        const std::uint64_t kv = slotKey(v);
        int b = a;
        for (; b > j && slotKey(sp[b - 1]) > kv; --b) sp[b] = sp[b - 1];
        sp[b] = v;
      }
      j = e;
    }
  }

  /// Sorts the n_ candidates, keeps the best K (kept_) at the front, or in place through
  /// order_ when `last` (finish()), tightens the threshold.
  GF_TARGET_AVX2_PATHS void reduce(bool last = false) {
    const int n = n_;
    std::uint32_t* const sp = order_;  // kBuf + 8: the tie check reads one past
    if (n <= kBuf / 2) {
      sortProxies<kBuf / 16>(d_, n, sp);
    } else {
      sortProxies<kBuf / 8>(d_, n, sp);
    }
    const int keep = std::min(n, k_);
    // Two of the first K + 1 whose distances differ only in the bits the slot replaced: their
    // order is the slots', not the keys' (rare: duplicate points, mostly).
    const int pairs = std::min(n, k_ + 1) - 1;  // adjacent pairs (j, j + 1), j < pairs
    bool near_tie = false;
    for (int j = 0; j < pairs; j += 8) {
      const __m256i a = _mm256_srli_epi32(
          _mm256_load_si256(reinterpret_cast<const __m256i*>(sp + j)), kProxyBits);
      const __m256i b = _mm256_srli_epi32(
          _mm256_loadu_si256(reinterpret_cast<const __m256i*>(sp + j + 1)), kProxyBits);
      const __m256i lane = _mm256_setr_epi32(j, j + 1, j + 2, j + 3, j + 4, j + 5, j + 6, j + 7);
      const __m256i eq = _mm256_and_si256(_mm256_cmpeq_epi32(a, b),
                                          _mm256_cmpgt_epi32(_mm256_set1_epi32(pairs), lane));
      near_tie |= !_mm256_testz_si256(eq, eq);
    }
    if (near_tie) sortTiedRuns(sp, n, keep);
    if (last) {
      ordered_ = true;
      n_ = kept_ = keep;
      if (kept_ == k_) thr_ = std::min(thr_, keyDist(key(k_ - 1)));
      return;
    }
    alignas(32) std::uint32_t nd[kBuf + 8], ni[kBuf + 8];
    for (int j = 0; j < keep; ++j) {
      const std::uint32_t s = sp[j] & kSlotMask;
      nd[j] = d_[s];
      ni[j] = i_[s];
    }
    std::memcpy(d_, nd, static_cast<std::size_t>(keep) * sizeof(std::uint32_t));
    std::memcpy(i_, ni, static_cast<std::size_t>(keep) * sizeof(std::uint32_t));
    n_ = kept_ = keep;
    if (kept_ == k_) thr_ = std::min(thr_, keyDist(key(k_ - 1)));
  }

  alignas(32) std::uint32_t d_[kBuf + 8];      // squared distance bits; the first kept_ sorted
  alignas(32) std::uint32_t i_[kBuf + 8];      // point indices
  alignas(32) std::uint32_t order_[kBuf + 8];  // the last sort's proxies (slots in the low bits)
  int k_ = 0, n_ = 0, kept_ = 0;
  float thr_ = 0.f;
  bool ordered_ = false;  // finish() sorted: the best K are d_ / i_ at the slots of order_
};

}  // namespace

GF_TARGET_AVX2_PATHS void queryRangeAvx2(const Tree& t, std::size_t pb, std::size_t pe, int k,
                                         std::int32_t* out_idx, float* out_dist) {
  if (k <= 16) {
    TopKAvx2<4> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 32) {
    TopKAvx2<8> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 64) {
    TopKProxyAvx2 set;
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

}  // namespace kdtree
}  // namespace ground_filter
