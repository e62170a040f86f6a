#ifndef GROUND_FILTER_SRC_CORE_SIMD_AVX512_COMMON_H
#define GROUND_FILTER_SRC_CORE_SIMD_AVX512_COMMON_H

// Shared by the AVX-512 code paths (kd-tree queries, neighbourhood PCA). They are compiled with a
// function target attribute and chosen at run time, so the package still runs on any x86-64.

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define GF_HAVE_AVX512 1
#define GF_TARGET_AVX512 __attribute__((target("avx512f")))

namespace ground_filter {
namespace simd {

/// \brief Keeps the compiler from fusing a product into a later addition (an FMA rounds
///        differently from the portable code, whose results the AVX-512 code must match).
GF_TARGET_AVX512 inline __m512 opaque(__m512 v) {
  asm("" : "+v"(v));
  return v;
}
/// \brief See opaque(__m512).
GF_TARGET_AVX512 inline __m512d opaque(__m512d v) {
  asm("" : "+v"(v));
  return v;
}
/// \brief See opaque(__m512).
GF_TARGET_AVX512 inline __m128 opaque(__m128 v) {
  asm("" : "+v"(v));
  return v;
}

/// \brief Whether this CPU runs AVX-512F code.
inline bool cpuHasAvx512() { return __builtin_cpu_supports("avx512f"); }

}  // namespace simd
}  // namespace ground_filter

#else
#define GF_HAVE_AVX512 0
#endif

#endif  // GROUND_FILTER_SRC_CORE_SIMD_AVX512_COMMON_H
