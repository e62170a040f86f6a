// The grid keys of the normal filter's two sorts (cell_keys.h): the portable loops and the AVX2
// path, four points at a time, compiled with a function target attribute and chosen at run time.

#include "normal/cell_keys.h"

#include "normal/cpu_gpu_common.h"
#include "simd/avx2_common.h"
#include "simd/simd.h"

namespace ground_filter {
namespace normal {

namespace {

void columnKeys(const float* xyz, std::size_t b, std::size_t e, double min_x, double min_y,
                double inv_cell, std::uint64_t* keys) {
  for (std::size_t i = b; i < e; ++i) {
    keys[i] = columnKey(cellIndex(xyz[3 * i], min_x, inv_cell),
                        cellIndex(xyz[3 * i + 1], min_y, inv_cell));
  }
}

void tileKeys(const float* xyz, std::size_t b, std::size_t e, double min_x, double min_y,
              double inv_tile, int y_bits, std::uint64_t* keys) {
  for (std::size_t i = b; i < e; ++i) {
    const std::uint64_t tx = cellIndex(xyz[3 * i], min_x, inv_tile);
    keys[i] = (tx << y_bits) | cellIndex(xyz[3 * i + 1], min_y, inv_tile);
  }
}

#if GF_HAVE_AVX2_PATHS
// spreadBits() of the four 64-bit lanes.
GF_TARGET_AVX2_PATHS inline __m256i spreadBits4(__m256i v) {
  v = _mm256_and_si256(_mm256_or_si256(v, _mm256_slli_epi64(v, 16)),
                       _mm256_set1_epi64x(0x0000ffff0000ffffLL));
  v = _mm256_and_si256(_mm256_or_si256(v, _mm256_slli_epi64(v, 8)),
                       _mm256_set1_epi64x(0x00ff00ff00ff00ffLL));
  v = _mm256_and_si256(_mm256_or_si256(v, _mm256_slli_epi64(v, 4)),
                       _mm256_set1_epi64x(0x0f0f0f0f0f0f0f0fLL));
  v = _mm256_and_si256(_mm256_or_si256(v, _mm256_slli_epi64(v, 2)),
                       _mm256_set1_epi64x(0x3333333333333333LL));
  v = _mm256_and_si256(_mm256_or_si256(v, _mm256_slli_epi64(v, 1)),
                       _mm256_set1_epi64x(0x5555555555555555LL));
  return v;
}

// cellIndex() of four coordinates into 64-bit lanes, the same double arithmetic; false where a
// cell reaches 2^31 (past the truncation to int32: the scalar code decides those points).
GF_TARGET_AVX2_PATHS inline bool cellIndex4(__m128 v, __m256d lo, __m256d inv, __m256i* cell) {
  const __m256d c = _mm256_mul_pd(_mm256_sub_pd(_mm256_cvtps_pd(v), lo), inv);
  if (_mm256_movemask_pd(_mm256_cmp_pd(c, _mm256_set1_pd(2147483648.0), _CMP_GE_OQ))) {
    return false;
  }
  // Below 1 the cell is 0, as in cellIndex() (also for a coordinate below the origin).
  const __m256d at_least_one = _mm256_cmp_pd(c, _mm256_set1_pd(1.0), _CMP_GE_OQ);
  *cell = _mm256_and_si256(_mm256_cvtepu32_epi64(_mm256_cvttpd_epi32(c)),
                           _mm256_castpd_si256(at_least_one));
  return true;
}

// The cells of points i .. i + 3: false where the scalar code must decide.
GF_TARGET_AVX2_PATHS inline bool cells4(const float* xyz, std::size_t i, __m256d lx, __m256d ly,
                                        __m256d inv, __m256i* cx, __m256i* cy) {
  const float* p = xyz + 3 * i;
  return cellIndex4(_mm_setr_ps(p[0], p[3], p[6], p[9]), lx, inv, cx) &&
         cellIndex4(_mm_setr_ps(p[1], p[4], p[7], p[10]), ly, inv, cy);
}

GF_TARGET_AVX2_PATHS void columnKeysAvx2(const float* xyz, std::size_t b, std::size_t e,
                                         double min_x, double min_y, double inv_cell,
                                         std::uint64_t* keys) {
  const __m256d lx = _mm256_set1_pd(min_x), ly = _mm256_set1_pd(min_y);
  const __m256d inv = _mm256_set1_pd(inv_cell);
  std::size_t i = b;
  for (; i + 4 <= e; i += 4) {
    __m256i cx, cy;
    if (!cells4(xyz, i, lx, ly, inv, &cx, &cy)) {
      columnKeys(xyz, i, i + 4, min_x, min_y, inv_cell, keys);
      continue;
    }
    const __m256i key = _mm256_or_si256(spreadBits4(cx), _mm256_slli_epi64(spreadBits4(cy), 1));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + i), key);
  }
  _mm256_zeroupper();  // see tileKeysAvx2()
  columnKeys(xyz, i, e, min_x, min_y, inv_cell, keys);
}

GF_TARGET_AVX2_PATHS void tileKeysAvx2(const float* xyz, std::size_t b, std::size_t e, double min_x,
                                       double min_y, double inv_tile, int y_bits,
                                       std::uint64_t* keys) {
  const __m256d lx = _mm256_set1_pd(min_x), ly = _mm256_set1_pd(min_y);
  const __m256d inv = _mm256_set1_pd(inv_tile);
  const __m128i shift = _mm_cvtsi32_si128(y_bits);
  std::size_t i = b;
  for (; i + 4 <= e; i += 4) {
    __m256i tx, ty;
    if (!cells4(xyz, i, lx, ly, inv, &tx, &ty)) {
      tileKeys(xyz, i, i + 4, min_x, min_y, inv_tile, y_bits, keys);
      continue;
    }
    const __m256i key = _mm256_or_si256(_mm256_sll_epi64(tx, shift), ty);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + i), key);
  }
  // GCC left the upper halves of the registers dirty on the way into the portable tail (no
  // vzeroupper before the call): the SSE code after it, the kd-tree build among it, then took
  // about 0.4 ms longer a KITTI frame on a Zen 5 guest.
  _mm256_zeroupper();
  tileKeys(xyz, i, e, min_x, min_y, inv_tile, y_bits, keys);
}
#endif

}  // namespace

void columnKeysOf(const float* xyz, std::size_t b, std::size_t e, double min_x, double min_y,
                  double inv_cell, std::uint64_t* keys) {
#if GF_HAVE_AVX2_PATHS
  if (simd::allows(simd::Level::kAvx2)) {
    columnKeysAvx2(xyz, b, e, min_x, min_y, inv_cell, keys);
    return;
  }
#endif
  columnKeys(xyz, b, e, min_x, min_y, inv_cell, keys);
}

void tileKeysOf(const float* xyz, std::size_t b, std::size_t e, double min_x, double min_y,
                double inv_tile, int y_bits, std::uint64_t* keys) {
#if GF_HAVE_AVX2_PATHS
  if (simd::allows(simd::Level::kAvx2)) {
    tileKeysAvx2(xyz, b, e, min_x, min_y, inv_tile, y_bits, keys);
    return;
  }
#endif
  tileKeys(xyz, b, e, min_x, min_y, inv_tile, y_bits, keys);
}

}  // namespace normal
}  // namespace ground_filter
