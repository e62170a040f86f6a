#ifndef GROUND_FILTER_SRC_CORE_SIMD_AVX2_COMMON_H
#define GROUND_FILTER_SRC_CORE_SIMD_AVX2_COMMON_H

// Shared by the AVX2 code paths (kd-tree queries, neighbourhood PCA) of CPUs without AVX-512.
// Compiled with a function target attribute (AVX2 without FMA: a fused product rounds
// differently from the portable code) and chosen at run time, so the package runs on any x86-64.

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>

#include <cstdint>
#define GF_HAVE_AVX2_PATHS 1
#define GF_TARGET_AVX2_PATHS __attribute__((target("avx2,popcnt")))

namespace ground_filter {
namespace simd {
namespace avx2 {

/// \brief Keeps the compiler from fusing a product into a later addition (see
///        avx512_common.h's opaque()).
GF_TARGET_AVX2_PATHS inline __m256 opaque(__m256 v) {
  asm("" : "+x"(v));
  return v;
}
/// \brief See opaque(__m256).
GF_TARGET_AVX2_PATHS inline __m256d opaque(__m256d v) {
  asm("" : "+x"(v));
  return v;
}
/// \brief See opaque(__m256).
GF_TARGET_AVX2_PATHS inline __m128 opaque(__m128 v) {
  asm("" : "+x"(v));
  return v;
}

/// \brief The lanes of each 8-bit mask's set bits, packed to the front (4 bits per lane).
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

/// \brief The permutation (for _mm256_permutevar8x32_*) that moves the lanes set in `mask`
///        (movemask bits) to the front, in order: a branch-free compress of eight lanes.
GF_TARGET_AVX2_PATHS inline __m256i compressPermutation(int mask) {
  const __m256i shifts = _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28);
  return _mm256_and_si256(
      _mm256_srlv_epi32(_mm256_set1_epi32(static_cast<int>(kCompress.lanes[mask])), shifts),
      _mm256_set1_epi32(0xf));
}

/// \brief Whether this CPU runs the AVX2 paths (AVX2 and POPCNT).
inline bool cpuHasAvx2() {
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
}

}  // namespace avx2
}  // namespace simd
}  // namespace ground_filter

#else
#define GF_HAVE_AVX2_PATHS 0
#endif

#endif  // GROUND_FILTER_SRC_CORE_SIMD_AVX2_COMMON_H
