#ifndef GROUND_FILTER_SRC_CORE_HAG_SURFACE_POINTS_H
#define GROUND_FILTER_SRC_CORE_HAG_SURFACE_POINTS_H

// What the ground surface's passes over a cloud share (height_above_ground.cpp, and the AVX2
// passes of surface_points_avx2.cpp): the records' x, y, z, the bilinear elevation, the sums of
// a cell's points, and the AVX2 passes' entry points.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

#include "ground_filter/cloud_view.h"
#include "simd/avx2_common.h"

namespace ground_filter {
namespace hag {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// x, y, z of a CloudView held in locals (see gatherGround()).
struct XyzReader {
  explicit XyzReader(const CloudView& c)
      : data(c.data()), stride(c.stride()), ox(c.xOffset()), oy(c.yOffset()), oz(c.zOffset()) {}
  bool get(std::size_t i, float* x, float* y, float* z) const {
    const std::uint8_t* p = data + i * stride;
    std::memcpy(x, p + ox, sizeof(float));
    std::memcpy(y, p + oy, sizeof(float));
    std::memcpy(z, p + oz, sizeof(float));
    return std::isfinite(*x) && std::isfinite(*y) && std::isfinite(*z);
  }
  // y and z follow x in the record, and 4 more bytes after z: a record's x y z is one 16-byte
  // load (the AVX2 paths' transposes).
  bool packed() const { return oy == ox + 4 && oz == ox + 8 && ox + 16 <= stride; }
  const std::uint8_t* data;
  std::size_t stride, ox, oy, oz;
};

// bilinear() where some of the four centres have no elevation (NaN): those drop out and the
// weights of the others are renormalised; none left: NaN. Out of line: the rare case.
inline __attribute__((noinline)) float bilinearPartial(float a, float b, float c, float d, float tx,
                                                       float ty) {
  const float v[4] = {a, b, c, d};
  const float w[4] = {(1.f - tx) * (1.f - ty), tx * (1.f - ty), (1.f - tx) * ty, tx * ty};
  float sw = 0.f, s = 0.f;
  for (int k = 0; k < 4; ++k) {
    if (!(w[k] > 0.f) || std::isnan(v[k])) continue;
    sw += w[k];
    s += w[k] * v[k];
  }
  return sw > 1e-6f ? s / sw : kNaN;
}

// Elevation at (tx, ty) in 0..1 between the centres a (lower left), b (right), c (above), d:
// bilinear, exact on a plane.
inline float bilinear(float a, float b, float c, float d, float tx, float ty) {
  const float lo = a + tx * (b - a), hi = c + tx * (d - c);
  const float z = lo + ty * (hi - lo);
  return z == z ? z : bilinearPartial(a, b, c, d, tx, ty);  // NaN: a centre without elevation
}

// What heights() needs of the surface, in locals.
struct Lookup {
  const float* centre;  // per grid cell: elevation at the centre, NaN none
  std::size_t nx;
  float x0, y0, inv, hi_u, hi_v;  // lower-left corner, 1 / cell, last u and v inside
};

// The sums of a run of points in one cell (GroundSurface::accumulate()), in the field order of
// GroundSurface::Accum: n, x, y, z | xx, xy, yy, zz | xz, yz. Portable code: ten doubles.
struct ScalarRun {
  double s[10];
  void reset() { std::fill(s, s + 10, 0.0); }
  void add(double dx, double dy, double dz) {
    s[0] += 1.0;
    s[1] += dx;
    s[2] += dy;
    s[3] += dz;
    s[4] += dx * dx;
    s[5] += dx * dy;
    s[6] += dy * dy;
    s[7] += dz * dz;
    s[8] += dx * dz;
    s[9] += dy * dz;
  }
  void addTo(double* acc) const {
    for (int j = 0; j < 10; ++j) acc[j] += s[j];
  }
};

#if GF_HAVE_AVX2_PATHS
// ScalarRun in three registers: the ten doubles would not fit the sixteen scalar registers,
// and their spills to the stack made each point wait on a store (2x slower). Lane by lane the
// same additions and products (not fused) in the same order: the same sums, bit for bit.
struct Avx2Run {
  __m256d a, b, c;  // n x y z | xx xy yy zz | xz yz - -
  GF_TARGET_AVX2_PATHS void reset() { a = b = c = _mm256_setzero_pd(); }
  GF_TARGET_AVX2_PATHS void add(double dx, double dy, double dz) {
    const __m256d d = _mm256_setr_pd(1.0, dx, dy, dz);
    a = _mm256_add_pd(a, d);
    const __m256d p = _mm256_permute4x64_pd(d, _MM_SHUFFLE(3, 2, 1, 1));  // x x y z
    const __m256d q = _mm256_permute4x64_pd(d, _MM_SHUFFLE(3, 2, 2, 1));  // x y y z
    b = _mm256_add_pd(b, simd::avx2::opaque(_mm256_mul_pd(p, q)));
    const __m256d r = _mm256_permute4x64_pd(d, _MM_SHUFFLE(3, 3, 3, 3));  // z z z z
    c = _mm256_add_pd(c, simd::avx2::opaque(_mm256_mul_pd(q, r)));        // xz yz yz zz
  }
  GF_TARGET_AVX2_PATHS void addTo(double* acc) const {
    _mm256_storeu_pd(acc, _mm256_add_pd(_mm256_loadu_pd(acc), a));
    _mm256_storeu_pd(acc + 4, _mm256_add_pd(_mm256_loadu_pd(acc + 4), b));
    _mm_storeu_pd(acc + 8, _mm_add_pd(_mm_loadu_pd(acc + 8), _mm256_castpd256_pd128(c)));
  }
};

/// \brief The finite points labelled 1 of `in` into px, py, pz from *k_io on, eight at a time from
///        point 0, for records whose x y z lie in 16 bytes (else nothing); the bounds b (min x,
///        min y, max x, max y) and *k_io carried in and out. Returns the point where it stopped.
GF_TARGET_AVX2_PATHS std::size_t gatherAvx2(const XyzReader& in, const std::uint8_t* label,
                                            std::size_t n, float* px, float* py, float* pz,
                                            std::size_t* k_io, float* b);
/// \brief The heights of points [0, returned) of `in` into h, eight at a time, the same values
///        bit for bit as one at a time (height_above_ground.cpp's heightsScalar()).
GF_TARGET_AVX2_PATHS std::size_t heightsAvx2(const XyzReader& in, const Lookup& at, std::size_t n,
                                             float* h);
#endif

}  // namespace hag
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_HAG_SURFACE_POINTS_H
