#ifndef GROUND_FILTER_SRC_CORE_SIMD_NEON_COMMON_H
#define GROUND_FILTER_SRC_CORE_SIMD_NEON_COMMON_H

// Shared by the NEON code paths of aarch64 (kd-tree queries, neighbourhood PCA, voxel passes).
// Advanced SIMD is part of every AArch64 CPU: no run-time check, only the SIMD level in force
// (simd.h, GF_SIMD=portable turns these paths off).

#if defined(__aarch64__) && defined(__ARM_NEON)
#include <arm_neon.h>
#define GF_HAVE_NEON_PATHS 1

namespace ground_filter {
namespace simd {
namespace neon {

/// \brief Keeps the compiler from fusing a product into a later addition (a fused multiply-add
///        rounds differently from the portable code, whose results the NEON code must match).
inline float32x4_t opaque(float32x4_t v) {
  asm("" : "+w"(v));
  return v;
}
/// \brief See opaque(float32x4_t).
inline float64x2_t opaque(float64x2_t v) {
  asm("" : "+w"(v));
  return v;
}

}  // namespace neon
}  // namespace simd
}  // namespace ground_filter

#else
#define GF_HAVE_NEON_PATHS 0
#endif

#endif  // GROUND_FILTER_SRC_CORE_SIMD_NEON_COMMON_H
