// The ground surface's two passes over a cloud on the AVX2 path (surface_points.h): the collection
// of the ground points and the heights, eight points at a time. Compiled with a function target
// attribute and chosen at run time (height_above_ground.cpp), so the package runs on any x86-64.

#include <algorithm>
#include <cstring>
#include <limits>

#include "hag/surface_points.h"

namespace ground_filter {
namespace hag {

#if GF_HAVE_AVX2_PATHS

namespace {

// x, y, z of the 8 records from `base` (in.packed()): 8 loads and two 4 x 4 transposes.
GF_TARGET_AVX2_PATHS inline void loadXyz8(const XyzReader& in, const std::uint8_t* base, __m256* x,
                                          __m256* y, __m256* z) {
  __m128 r[8];
  for (int k = 0; k < 8; ++k) {
    r[k] = _mm_loadu_ps(reinterpret_cast<const float*>(base + k * in.stride + in.ox));
  }
  _MM_TRANSPOSE4_PS(r[0], r[1], r[2], r[3]);
  _MM_TRANSPOSE4_PS(r[4], r[5], r[6], r[7]);
  *x = _mm256_insertf128_ps(_mm256_castps128_ps256(r[0]), r[4], 1);
  *y = _mm256_insertf128_ps(_mm256_castps128_ps256(r[1]), r[5], 1);
  *z = _mm256_insertf128_ps(_mm256_castps128_ps256(r[2]), r[6], 1);
}

// All-ones lanes where x, y and z are finite (0 * v is 0, NaN for NaN and Inf).
GF_TARGET_AVX2_PATHS inline __m256 finiteLanes(__m256 x, __m256 y, __m256 z) {
  const __m256 zero = _mm256_setzero_ps();
  const __m256 f = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(x, zero), _mm256_mul_ps(y, zero)),
                                 _mm256_mul_ps(z, zero));
  return _mm256_cmp_ps(f, zero, _CMP_EQ_OQ);
}

// p[g] and p[g + 1] of the eight indices g: each pair one 8-byte element of a gather, half as
// many elements as two float gathers (a gather's cost grows with its elements).
GF_TARGET_AVX2_PATHS inline void gatherPairs(const float* p, __m256i g, __m256* first,
                                             __m256* second) {
  const long long* q = reinterpret_cast<const long long*>(p);
  const __m256 lo = _mm256_castsi256_ps(_mm256_i32gather_epi64(q, _mm256_castsi256_si128(g), 4));
  const __m256 hi =
      _mm256_castsi256_ps(_mm256_i32gather_epi64(q, _mm256_extracti128_si256(g, 1), 4));
  // lo: f0 s0 f1 s1 | f2 s2 f3 s3, hi: f4 s4 f5 s5 | f6 s6 f7 s7; the shuffles give
  // f0 f1 f4 f5 | f2 f3 f6 f7, and the 64-bit permutation the lane order.
  const __m256 f = _mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0));
  const __m256 s = _mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1));
  *first = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(f), _MM_SHUFFLE(3, 1, 2, 0)));
  *second = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(s), _MM_SHUFFLE(3, 1, 2, 0)));
}

}  // namespace

// gatherGround()'s loop eight points at a time from point 0, for packed records (else it does
// nothing): the kept points compressed to the front of each block of 8 (a table permutation, no
// branch on the labels, which alternate in short runs); k and the bounds (min x, min y, max x,
// max y) carried in and out. Returns where it stopped. The same points, order and bounds as the
// scalar loop.
GF_TARGET_AVX2_PATHS std::size_t gatherAvx2(const XyzReader& in, const std::uint8_t* label,
                                            std::size_t n, float* px, float* py, float* pz,
                                            std::size_t* k_io, float* b) {
  if (!in.packed()) return 0;
  const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  const __m256 ninf = _mm256_set1_ps(-std::numeric_limits<float>::infinity());
  const __m256i one = _mm256_set1_epi32(1);
  __m256 min_x = _mm256_set1_ps(b[0]), min_y = _mm256_set1_ps(b[1]);
  __m256 max_x = _mm256_set1_ps(b[2]), max_y = _mm256_set1_ps(b[3]);
  std::size_t k = *k_io, i = 0;
  for (; i + 8 <= n; i += 8) {  // k + 8 <= i + 8 <= n: every store inside the arrays
    __m256 x, y, z;
    loadXyz8(in, in.data + i * in.stride, &x, &y, &z);
    std::uint64_t l8;
    std::memcpy(&l8, label + i, sizeof l8);
    const __m256i ground = _mm256_cmpeq_epi32(
        _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(static_cast<long long>(l8))), one);
    const __m256 keep = _mm256_and_ps(_mm256_castsi256_ps(ground), finiteLanes(x, y, z));
    const int mask = _mm256_movemask_ps(keep);
    const __m256i perm = simd::avx2::compressPermutation(mask);
    _mm256_storeu_ps(px + k, _mm256_permutevar8x32_ps(x, perm));
    _mm256_storeu_ps(py + k, _mm256_permutevar8x32_ps(y, perm));
    _mm256_storeu_ps(pz + k, _mm256_permutevar8x32_ps(z, perm));
    k += static_cast<std::size_t>(__builtin_popcount(static_cast<unsigned>(mask)));
    min_x = _mm256_min_ps(min_x, _mm256_blendv_ps(inf, x, keep));
    min_y = _mm256_min_ps(min_y, _mm256_blendv_ps(inf, y, keep));
    max_x = _mm256_max_ps(max_x, _mm256_blendv_ps(ninf, x, keep));
    max_y = _mm256_max_ps(max_y, _mm256_blendv_ps(ninf, y, keep));
  }
  alignas(32) float v[4][8];
  _mm256_store_ps(v[0], min_x);
  _mm256_store_ps(v[1], min_y);
  _mm256_store_ps(v[2], max_x);
  _mm256_store_ps(v[3], max_y);
  for (int j = 0; j < 8; ++j) {
    b[0] = std::min(b[0], v[0][j]);
    b[1] = std::min(b[1], v[1][j]);
    b[2] = std::max(b[2], v[2][j]);
    b[3] = std::max(b[3], v[3][j]);
  }
  *k_io = k;
  return i;
}

// heightsScalar() eight points at a time, from point 0; returns where it stopped (the scalar
// code does the rest). The same operations in the same order (no fused products): the same
// heights bit for bit.
GF_TARGET_AVX2_PATHS std::size_t heightsAvx2(const XyzReader& in, const Lookup& at, std::size_t n,
                                             float* h) {
  if (in.stride > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max() / 8) ||
      at.nx * 2 > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    return 0;
  }
  const int st = static_cast<int>(in.stride);
  const __m256i lane = _mm256_setr_epi32(0, st, 2 * st, 3 * st, 4 * st, 5 * st, 6 * st, 7 * st);
  const __m256 x0 = _mm256_set1_ps(at.x0), y0 = _mm256_set1_ps(at.y0);
  const __m256 inv = _mm256_set1_ps(at.inv), half = _mm256_set1_ps(0.5f);
  const __m256 hi_u = _mm256_set1_ps(at.hi_u), hi_v = _mm256_set1_ps(at.hi_v);
  const __m256 zero = _mm256_setzero_ps(), nan = _mm256_set1_ps(kNaN);
  const __m256i nx = _mm256_set1_epi32(static_cast<int>(at.nx));
  const float* c = at.centre;
  const int row = static_cast<int>(at.nx);
  const bool packed = in.packed();
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const std::uint8_t* base = in.data + i * in.stride;
    __m256 x, y, z;
    if (packed) {
      loadXyz8(in, base, &x, &y, &z);
    } else {
      x = _mm256_i32gather_ps(reinterpret_cast<const float*>(base + in.ox), lane, 1);
      y = _mm256_i32gather_ps(reinterpret_cast<const float*>(base + in.oy), lane, 1);
      z = _mm256_i32gather_ps(reinterpret_cast<const float*>(base + in.oz), lane, 1);
    }
    __m256 u = _mm256_sub_ps(_mm256_mul_ps(_mm256_sub_ps(x, x0), inv), half);
    __m256 v = _mm256_sub_ps(_mm256_mul_ps(_mm256_sub_ps(y, y0), inv), half);
    const __m256 in_grid = _mm256_and_ps(
        _mm256_and_ps(finiteLanes(x, y, z), _mm256_cmp_ps(u, zero, _CMP_GE_OQ)),
        _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps(v, zero, _CMP_GE_OQ), _mm256_cmp_ps(u, hi_u, _CMP_LT_OQ)),
            _mm256_cmp_ps(v, hi_v, _CMP_LT_OQ)));
    u = _mm256_and_ps(u, in_grid);  // lanes outside: cell 0 (a valid address), NaN below
    v = _mm256_and_ps(v, in_grid);
    const __m256i i0 = _mm256_cvttps_epi32(u), j0 = _mm256_cvttps_epi32(v);
    const __m256 tx = _mm256_sub_ps(u, _mm256_cvtepi32_ps(i0));
    const __m256 ty = _mm256_sub_ps(v, _mm256_cvtepi32_ps(j0));
    const __m256i g = _mm256_add_epi32(_mm256_mullo_epi32(j0, nx), i0);
    __m256 a, b, cc, d;
    gatherPairs(c, g, &a, &b);
    gatherPairs(c + row, g, &cc, &d);
    const __m256 lo = _mm256_add_ps(a, _mm256_mul_ps(tx, _mm256_sub_ps(b, a)));
    const __m256 hi = _mm256_add_ps(cc, _mm256_mul_ps(tx, _mm256_sub_ps(d, cc)));
    const __m256 e = _mm256_add_ps(lo, _mm256_mul_ps(ty, _mm256_sub_ps(hi, lo)));
    _mm256_storeu_ps(h + i, _mm256_blendv_ps(nan, _mm256_sub_ps(z, e), in_grid));
    // A centre without elevation in a lane inside the grid: the renormalised blend.
    int partial = _mm256_movemask_ps(_mm256_and_ps(in_grid, _mm256_cmp_ps(e, e, _CMP_UNORD_Q)));
    while (partial != 0) {
      const int k = __builtin_ctz(static_cast<unsigned>(partial));
      partial &= partial - 1;
      alignas(32) float va[8], vb[8], vc[8], vd[8], vtx[8], vty[8], vz[8];
      _mm256_store_ps(va, a);
      _mm256_store_ps(vb, b);
      _mm256_store_ps(vc, cc);
      _mm256_store_ps(vd, d);
      _mm256_store_ps(vtx, tx);
      _mm256_store_ps(vty, ty);
      _mm256_store_ps(vz, z);
      h[i + k] = vz[k] - bilinearPartial(va[k], vb[k], vc[k], vd[k], vtx[k], vty[k]);
    }
  }
  return i;
}

#endif  // GF_HAVE_AVX2_PATHS

}  // namespace hag
}  // namespace ground_filter
