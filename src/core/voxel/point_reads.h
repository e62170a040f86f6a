// Private to the voxel filter: how the voxelizer's passes read a point (the V4 operations,
// SSE2, NEON or plain floats, and where x y z come from), shared by prepare() (voxelize.cpp) and
// build() (voxelize_build.cpp).
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_POINT_READS_H
#define GROUND_FILTER_SRC_CORE_VOXEL_POINT_READS_H

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "ground_filter/cloud_view.h"
#include "simd/neon_common.h"
#include "voxel/avx2_passes.h"
#include "voxel/voxelize.h"

namespace ground_filter {
namespace voxel {

// Four floats x y z 0 of one point, implementations with the same results lane by lane, chosen
// per scan (Voxelizer::prepare()): the vector one of the architecture, Sse (SSE2, every x86-64,
// SIMD level sse and up) or Neon (every aarch64, SIMD level neon), and Plain (plain floats: SIMD
// level portable). Each one's operations are static functions; the passes below are templates
// on the implementation (O).
struct Plain {
  struct V {
    float v[4];
  };
  static V v4Load(const float* p) { return V{{p[0], p[1], p[2], p[3]}}; }
  static V v4LoadUnaligned(const float* p) { return v4Load(p); }
  static void v4Store(float* p, V a) {
    for (int k = 0; k < 4; ++k) p[k] = a.v[k];
  }
  static V v4Set(float x, float y, float z) { return V{{x, y, z, 0.f}}; }
  static V v4Splat(float a) { return V{{a, a, a, a}}; }
  static V v4Sub(V a, V b) {
    for (int k = 0; k < 4; ++k) a.v[k] -= b.v[k];
    return a;
  }
  static V v4Min(V a, V b) {
    for (int k = 0; k < 4; ++k) a.v[k] = a.v[k] < b.v[k] ? a.v[k] : b.v[k];
    return a;
  }
  static V v4Max(V a, V b) {
    for (int k = 0; k < 4; ++k) a.v[k] = a.v[k] > b.v[k] ? a.v[k] : b.v[k];
    return a;
  }
  static V v4Add(V a, V b) {
    for (int k = 0; k < 4; ++k) a.v[k] += b.v[k];
    return a;
  }
  static void v4StoreUnaligned(float* p, V a) { v4Store(p, a); }
  static V v4WithNegZ(V p) { return V{{p.v[0], p.v[1], p.v[2], -p.v[2]}}; }
  static V v4SumsAndRange(V s, V h) { return V{{s.v[0], s.v[1], s.v[2], h.v[3] + h.v[2]}}; }
  static bool v4Finite(V p) {
    return (p.v[0] - p.v[0]) + (p.v[1] - p.v[1]) + (p.v[2] - p.v[2]) == 0.f;
  }
  static V v4ZeroIf(V s, bool restart) { return restart ? v4Splat(0.f) : s; }
  static V v4LowestIf(V h, bool restart) {
    return restart ? v4Splat(-std::numeric_limits<float>::infinity()) : h;
  }
  static void v4Cells(V p, float inv, const std::int32_t* last, std::uint32_t* out) {
    for (int k = 0; k < 3; ++k) {
      out[k] =
          std::min(static_cast<std::uint32_t>(p.v[k] * inv), static_cast<std::uint32_t>(last[k]));
    }
  }
};

#if defined(__SSE2__)
struct Sse {
  using V = __m128;
  static V v4Load(const float* p) { return _mm_load_ps(p); }  // p 16-byte aligned
  static V v4LoadUnaligned(const float* p) { return _mm_loadu_ps(p); }
  // x y z of p[0..2] and lane 3 zero (p[3] is read: it must exist).
  static V v4LoadXyz0(const float* p) {
    return _mm_and_ps(_mm_loadu_ps(p), _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1)));
  }
  static void v4Store(float* p, V v) { _mm_store_ps(p, v); }
  static V v4Set(float x, float y, float z) { return _mm_set_ps(0.f, z, y, x); }
  static V v4Splat(float a) { return _mm_set1_ps(a); }
  static V v4Sub(V a, V b) { return _mm_sub_ps(a, b); }
  static V v4Min(V a, V b) { return _mm_min_ps(a, b); }  // a < b ? a : b
  static V v4Max(V a, V b) { return _mm_max_ps(a, b); }  // a > b ? a : b
  static V v4Add(V a, V b) { return _mm_add_ps(a, b); }
  static void v4StoreUnaligned(float* p, V v) { _mm_storeu_ps(p, v); }
  // (x, y, z, -z) of (x, y, z, w): negation is exact.
  static V v4WithNegZ(V p) {
    const V sign =
        _mm_castsi128_ps(_mm_set_epi32(std::numeric_limits<std::int32_t>::min(), 0, 0, 0));
    return _mm_xor_ps(_mm_shuffle_ps(p, p, _MM_SHUFFLE(2, 2, 1, 0)), sign);
  }
  // (s0, s1, s2, h2 + h3): with h2 = max z and h3 = -min z, lane 3 is max z - min z exactly.
  static V v4SumsAndRange(V s, V h) {
    const V r = _mm_add_ps(h, _mm_shuffle_ps(h, h, _MM_SHUFFLE(2, 2, 2, 2)));  // lane 3: h3 + h2
    const V t = _mm_shuffle_ps(s, r, _MM_SHUFFLE(3, 3, 2, 2));                 // s2 s2 r3 r3
    return _mm_shuffle_ps(s, t, _MM_SHUFFLE(2, 0, 1, 0));
  }
  // x - x is 0 for finite x and NaN for NaN/Inf: one test for all lanes.
  static bool v4Finite(V p) {
    return _mm_movemask_ps(_mm_cmpeq_ps(_mm_sub_ps(p, p), _mm_setzero_ps())) == 0xF;
  }
  // restart ? +0 : s, and restart ? -inf : h, as bit masks (no multiply or add in the dependency
  // chains of the gather's running sums and maxima).
  static V v4ZeroIf(V s, bool restart) {
    alignas(16) static const std::uint32_t kMask[2][4] = {{~0u, ~0u, ~0u, ~0u}, {0, 0, 0, 0}};
    return _mm_and_ps(s, _mm_load_ps(reinterpret_cast<const float*>(kMask[restart])));
  }
  static V v4LowestIf(V h, bool restart) {
    alignas(16) static const std::uint32_t kNegInf[2][4] = {
        {0, 0, 0, 0}, {0xFF800000u, 0xFF800000u, 0xFF800000u, 0xFF800000u}};
    return _mm_or_ps(v4ZeroIf(h, restart),
                     _mm_load_ps(reinterpret_cast<const float*>(kNegInf[restart])));
  }
  // min(int(p * inv), last) per lane (p >= 0 and below 2^22: the axis checks of prepare()).
  static void v4Cells(V p, float inv, const std::int32_t* last, std::uint32_t* out) {
    const __m128i vlast = _mm_loadu_si128(reinterpret_cast<const __m128i*>(last));
    __m128i q = _mm_cvttps_epi32(_mm_mul_ps(p, _mm_set1_ps(inv)));
    const __m128i over = _mm_cmpgt_epi32(q, vlast);
    q = _mm_or_si128(_mm_and_si128(over, vlast), _mm_andnot_si128(over, q));
    out[0] = static_cast<std::uint32_t>(_mm_cvtsi128_si32(q));
    out[1] = static_cast<std::uint32_t>(_mm_cvtsi128_si32(_mm_srli_si128(q, 4)));
    out[2] = static_cast<std::uint32_t>(_mm_cvtsi128_si32(_mm_srli_si128(q, 8)));
  }
};
using Vec = Sse;
constexpr bool kHaveVec = true;
#elif GF_HAVE_NEON_PATHS
struct Neon {
  using V = float32x4_t;
  static V v4Load(const float* p) { return vld1q_f32(p); }
  static V v4LoadUnaligned(const float* p) { return vld1q_f32(p); }
  static V v4LoadXyz0(const float* p) {  // see Sse::v4LoadXyz0()
    const uint32x4_t xyz = {~0u, ~0u, ~0u, 0u};
    return vreinterpretq_f32_u32(
        vandq_u32(vld1q_u32(reinterpret_cast<const std::uint32_t*>(p)), xyz));
  }
  static void v4Store(float* p, V v) { vst1q_f32(p, v); }
  static V v4Set(float x, float y, float z) { return V{x, y, z, 0.f}; }
  static V v4Splat(float a) { return vdupq_n_f32(a); }
  static V v4Sub(V a, V b) { return vsubq_f32(a, b); }
  // a < b ? a : b and a > b ? a : b, as Plain and SSE (fmin / fmax differ for NaN).
  static V v4Min(V a, V b) { return vbslq_f32(vcltq_f32(a, b), a, b); }
  static V v4Max(V a, V b) { return vbslq_f32(vcgtq_f32(a, b), a, b); }
  static V v4Add(V a, V b) { return vaddq_f32(a, b); }
  static void v4StoreUnaligned(float* p, V v) { vst1q_f32(p, v); }
  static V v4WithNegZ(V p) { return vsetq_lane_f32(-vgetq_lane_f32(p, 2), p, 3); }
  static V v4SumsAndRange(V s, V h) {
    return vsetq_lane_f32(vgetq_lane_f32(h, 3) + vgetq_lane_f32(h, 2), s, 3);
  }
  static bool v4Finite(V p) {  // as Sse::v4Finite()
    return vminvq_u32(vceqq_f32(vsubq_f32(p, p), vdupq_n_f32(0.f))) != 0;
  }
  static V v4ZeroIf(V s, bool restart) {  // bit masks, as Sse
    return vreinterpretq_f32_u32(
        vandq_u32(vreinterpretq_u32_f32(s), vdupq_n_u32(restart ? 0u : ~0u)));
  }
  static V v4LowestIf(V h, bool restart) {
    return vbslq_f32(vdupq_n_u32(restart ? ~0u : 0u),
                     vdupq_n_f32(-std::numeric_limits<float>::infinity()), h);
  }
  // min(int(p * inv), last) per lane (p >= 0 and below 2^22, as Sse).
  static void v4Cells(V p, float inv, const std::int32_t* last, std::uint32_t* out) {
    const int32x4_t q = vminq_s32(vcvtq_s32_f32(vmulq_n_f32(p, inv)), vld1q_s32(last));
    out[0] = static_cast<std::uint32_t>(vgetq_lane_s32(q, 0));
    out[1] = static_cast<std::uint32_t>(vgetq_lane_s32(q, 1));
    out[2] = static_cast<std::uint32_t>(vgetq_lane_s32(q, 2));
  }
};
using Vec = Neon;
constexpr bool kHaveVec = true;
#else
using Vec = Plain;  // never chosen (kHaveVec): Voxelizer::useVector() is false
constexpr bool kHaveVec = false;
#endif

// Whether O is a vector implementation (reads records in place, DirectPoints).
template <class O>
constexpr bool kIsVector = !std::is_same<O, Plain>::value;

// Calls f(O{}) with the implementation of the V4 operations: Vec or Plain.
template <class F>
void withOps(bool vec, F&& f) {
  if (kHaveVec && vec) {
    f(Vec{});
  } else {
    f(Plain{});
  }
}

// Where the key pass and the gather read a point's x y z (lane 3 zero): the aligned copy made
// by the first pass, or the input records themselves (x y z adjacent, records of at most 16
// bytes, SSE2: no copy to write and read back; Voxelizer::prepare()).
template <class O>
struct CopyPoints {
  using V4 = typename O::V;
  const float* xyz0;  // x y z 0 per input point, 16-byte aligned
  V4 load(std::size_t i) const { return O::v4Load(xyz0 + 4 * i); }
  V4 loadXyz(std::size_t i) const { return load(i); }
  const void* address(std::size_t i) const { return xyz0 + 4 * i; }
  std::size_t stride() const { return 4 * sizeof(float); }
  // The copy as records for the AVX2 passes: every one has 16 bytes.
  DirectRead rows() const {
    return DirectRead{reinterpret_cast<const std::uint8_t*>(xyz0), 16, ~std::size_t{0}};
  }
};
// Any layout: three scalar reads a record (first pass only; the other passes read the copy).
template <class O>
struct FieldPoints {
  using V4 = typename O::V;
  CloudView view;
  V4 load(std::size_t i) const { return O::v4Set(view.x(i), view.y(i), view.z(i)); }
  const void* address(std::size_t i) const { return view.data() + i * view.stride(); }
  std::size_t stride() const { return view.stride(); }
};
// The input records in place (x y z adjacent, vector implementations only).
template <class O>
struct DirectPoints {
  using V4 = typename O::V;
  Voxelizer::DirectRead d;
  V4 load(std::size_t i) const {
    const std::uint8_t* r = d.x + i * d.step;
    if (i < d.vector_end) {  // taken for all but the last record of packed x y z clouds
      return O::v4LoadXyz0(reinterpret_cast<const float*>(r));
    }
    float c[3];
    std::memcpy(c, r, sizeof(c));
    return O::v4Set(c[0], c[1], c[2]);
  }
  // x y z and a fourth lane of any value (the gather replaces it: no mask).
  V4 loadXyz(std::size_t i) const {
    return i < d.vector_end ? O::v4LoadUnaligned(reinterpret_cast<const float*>(d.x + i * d.step))
                            : load(i);
  }
  const void* address(std::size_t i) const { return d.x + i * d.step; }
  std::size_t stride() const { return d.step; }
  DirectRead rows() const { return d; }
};

// Calls f with where the key pass and the gather read the points: `copy` (x y z 0 per point),
// or, vector implementations only, the input records in place when there is no copy (prepare()
// makes the copy for every layout when it runs Plain).
template <class O, class F>
void withPoints(const Voxelizer::DirectRead& direct, const float* copy, F&& f) {
  if constexpr (kIsVector<O>) {
    if (!copy) {
      f(DirectPoints<O>{direct});
      return;
    }
  }
  f(CopyPoints<O>{copy});
}

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_POINT_READS_H
