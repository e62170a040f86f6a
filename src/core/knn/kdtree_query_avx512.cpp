// KdTreeNeighborSearch: the AVX-512 top-K set (bitonic network on zmm registers of keys).

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>

#include "knn/kdtree_tree.h"
#include "simd/avx2_common.h"
#include "simd/avx512_common.h"
#include "simd/simd.h"

namespace ground_filter {
namespace kdtree {

#if GF_HAVE_AVX512

// GCC's intrinsics start some results from _mm512_undefined_*(), which -Wmaybe-uninitialized
// reports at every inlined use (a known false positive).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

namespace {  // the set and its helpers; only the entry point below is shared

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
  static constexpr bool kSearchesByGroups = true;  // in queryRange() (AVX2 box tests)
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

}  // namespace

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

}  // namespace kdtree
}  // namespace ground_filter
