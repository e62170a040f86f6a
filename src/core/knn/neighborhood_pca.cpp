// The PCA of neighbour lists (stage "pca" of the normal filter, also fused into the kd-tree
// queries): covariance of every K neighbourhood and its eigen
// decomposition, in double. With AVX-512 the nine sums of a neighbourhood are kept in two
// registers, with AVX2 in three, with NEON (aarch64) in four (lane by lane the same additions in
// the same order, products not fused: the same bits as the scalar code). One neighbourhood per lane
// with gathers was 1.5x slower on Zen 4. The filter itself only needs each point's candidate bit:
// computeRowsCandidates() and friends decide it without the eigen solver where that is certain (see
// "Candidate decision" below).

#include "knn/neighborhood_pca.h"

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "common/threads_timing.h"
#include "knn/pca_cpu_gpu_common.h"
#include "simd/avx2_common.h"
#include "simd/avx512_common.h"
#include "simd/neon_common.h"
#include "simd/simd.h"

namespace ground_filter {

namespace {

/// Sums of a neighbourhood's offsets from its query point and of their products
/// (pca_cpu_gpu_common.h: the GPU's PCA sums the same way).
using Moments = NeighborhoodSums;

/// One pass over the neighbours, in double (the reference bits of every SIMD path below).
inline void sumsScalar(const float* xyz, const std::int32_t* row, int k, std::size_t query,
                       Moments* s) {
  *s = neighborhoodSums(xyz, row, k, xyz[3 * query], xyz[3 * query + 1], xyz[3 * query + 2]);
}

#if GF_HAVE_AVX512

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

using simd::opaque;

/// x y z of the point at `p` as doubles in lanes 0-2 (the other lanes are not used).
GF_TARGET_AVX512 inline __m512d loadXyz(const float* p) {
  return _mm512_cvtps_pd(_mm256_castps128_ps256(
      _mm_castsi128_ps(_mm512_castsi512_si128(_mm512_maskz_loadu_epi32(0x7, p)))));
}

/// The offset of the point at `p` from `o` (loadXyz() of the query): dx dy dz 0 0 0 0 0.
GF_TARGET_AVX512 inline __m512d offsetOf(const float* p, __m512d o) {
  return _mm512_maskz_sub_pd(0x7, loadXyz(p), o);
}

/// The six products of an offset d: dx dx, dx dy, dx dz, dy dy, dy dz, dz dz (lanes 0-5).
GF_TARGET_AVX512 inline __m512d productsOf(__m512d d) {
  const __m512i pa = _mm512_set_epi64(3, 3, 2, 1, 1, 0, 0, 0);  // dx dx dx dy dy dz
  const __m512i pb = _mm512_set_epi64(3, 3, 2, 2, 1, 2, 1, 0);  // dx dy dz dy dz dz
  return _mm512_mul_pd(_mm512_permutexvar_pd(pa, d), _mm512_permutexvar_pd(pb, d));
}

/// Moments from the lanes [sx sy sz - ...] and [sxx sxy sxz syy syz szz - -] of `k` neighbours.
GF_TARGET_AVX512 inline Moments momentsOf(__m512d s1, __m512d s2, int k) {
  alignas(64) double a[8], b[8];
  _mm512_store_pd(a, s1);
  _mm512_store_pd(b, s2);
  return Moments{a[0], a[1], a[2], b[0], b[1], b[2], b[3], b[4], b[5], k};
}

/// sumsScalar() of a full row (k valid entries): lanes [sx sy sz - - - - -] and
/// [sxx sxy sxz syy syz szz - -], each lane added to in neighbour order.
GF_TARGET_AVX512 void sumsAvx512(const float* xyz, const std::int32_t* row, int k,
                                 std::size_t query, Moments* s) {
  const __m512d o = loadXyz(xyz + 3 * query);
  __m512d s1 = _mm512_setzero_pd(), s2 = _mm512_setzero_pd();
  for (int j = 0; j < k; ++j) {
    const __m512d d = offsetOf(xyz + 3 * static_cast<std::size_t>(row[j]), o);
    s1 = _mm512_add_pd(s1, d);
    s2 = _mm512_add_pd(s2, opaque(productsOf(d)));  // products not fused into the sums
  }
  *s = momentsOf(s1, s2, k);
}

/// Sums of a full row for the candidate decision only: two accumulator pairs (even and odd
/// neighbours) so the additions do not wait on each other; NOT the reference bits (a different
/// addition order), so a point the fast decision cannot certify recomputes sumsAvx512().
GF_TARGET_AVX512 void sumsAvx512Fast(const float* xyz, const std::int32_t* row, int k,
                                     std::size_t query, Moments* s) {
  const __m512d o = loadXyz(xyz + 3 * query);
  __m512d s1 = _mm512_setzero_pd(), s2 = _mm512_setzero_pd();
  __m512d t1 = _mm512_setzero_pd(), t2 = _mm512_setzero_pd();
  int j = 0;
  for (; j + 1 < k; j += 2) {
    const __m512d d = offsetOf(xyz + 3 * static_cast<std::size_t>(row[j]), o);
    const __m512d e = offsetOf(xyz + 3 * static_cast<std::size_t>(row[j + 1]), o);
    s1 = _mm512_add_pd(s1, d);
    t1 = _mm512_add_pd(t1, e);
    s2 = _mm512_add_pd(s2, productsOf(d));
    t2 = _mm512_add_pd(t2, productsOf(e));
  }
  for (; j < k; ++j) {
    const __m512d d = offsetOf(xyz + 3 * static_cast<std::size_t>(row[j]), o);
    s1 = _mm512_add_pd(s1, d);
    s2 = _mm512_add_pd(s2, productsOf(d));
  }
  *s = momentsOf(_mm512_add_pd(s1, t1), _mm512_add_pd(s2, t2), k);
}

#pragma GCC diagnostic pop

// Asked per call: the SIMD level in force can change (tests run every level in one process).
bool haveAvx512() {
  static const bool has = simd::cpuHasAvx512();
  return has && simd::allows(simd::Level::kAvx512);
}

#else

bool haveAvx512() { return false; }

#endif  // GF_HAVE_AVX512

#if GF_HAVE_AVX2_PATHS

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

// AVX2 (no AVX-512): the nine sums in three registers of four doubles, [sx sy sz -],
// [sxx sxy sxz syy] and [syz szz - -], each lane added to in the same order as the AVX-512 and
// scalar code (same bits).

/// The offset of the point at `p` from `o` (the query's x y z 0): dx dy dz 0.
GF_TARGET_AVX2_PATHS inline __m256d offsetOf4(const float* p, __m256d o) {
  const __m128 xyz = _mm_maskload_ps(p, _mm_setr_epi32(-1, -1, -1, 0));  // no read past p[2]
  return _mm256_sub_pd(_mm256_cvtps_pd(xyz), o);
}

/// dx dx, dx dy, dx dz, dy dy (lanes 0-3) and dy dz, dz dz, 0, 0 of an offset d (d[3] = 0).
GF_TARGET_AVX2_PATHS inline void productsOf4(__m256d d, __m256d* p1, __m256d* p2) {
  *p1 = _mm256_mul_pd(_mm256_permute4x64_pd(d, _MM_SHUFFLE(1, 0, 0, 0)),
                      _mm256_permute4x64_pd(d, _MM_SHUFFLE(1, 2, 1, 0)));
  *p2 = _mm256_mul_pd(_mm256_permute4x64_pd(d, _MM_SHUFFLE(3, 3, 2, 1)),
                      _mm256_permute4x64_pd(d, _MM_SHUFFLE(3, 3, 2, 2)));
}

GF_TARGET_AVX2_PATHS inline Moments momentsOf4(__m256d s1, __m256d s2, __m256d s3, int k) {
  alignas(32) double a[4], b[4], c[4];
  _mm256_store_pd(a, s1);
  _mm256_store_pd(b, s2);
  _mm256_store_pd(c, s3);
  return Moments{a[0], a[1], a[2], b[0], b[1], b[2], b[3], c[0], c[1], k};
}

/// sumsScalar() of a full row (k valid entries), the same bits (see sumsAvx512()).
GF_TARGET_AVX2_PATHS void sumsAvx2(const float* xyz, const std::int32_t* row, int k,
                                   std::size_t query, Moments* s) {
  using simd::avx2::opaque;
  const __m256d o = offsetOf4(xyz + 3 * query, _mm256_setzero_pd());
  __m256d s1 = _mm256_setzero_pd(), s2 = _mm256_setzero_pd(), s3 = _mm256_setzero_pd();
  for (int j = 0; j < k; ++j) {
    const __m256d d = offsetOf4(xyz + 3 * static_cast<std::size_t>(row[j]), o);
    __m256d p1, p2;
    productsOf4(d, &p1, &p2);
    s1 = _mm256_add_pd(s1, d);
    s2 = _mm256_add_pd(s2, opaque(p1));  // products not fused into the sums
    s3 = _mm256_add_pd(s3, opaque(p2));
  }
  *s = momentsOf4(s1, s2, s3, k);
}

/// The sums of the lanes of a and of b: [sum a, sum b].
GF_TARGET_AVX2_PATHS inline __m128d laneSums2(__m256d a, __m256d b) {
  const __m256d h = _mm256_hadd_pd(a, b);  // a0+a1 b0+b1 a2+a3 b2+b3
  return _mm_add_pd(_mm256_castpd256_pd128(h), _mm256_extractf128_pd(h, 1));
}

/// Sums of a full row for the candidate decision only (not the reference bits: a point the fast
/// decision cannot certify recomputes sumsAvx2()). Four neighbours a step, transposed: x, y, z
/// of four neighbours in one register each and every one of the nine sums in its own register
/// (lane i sums neighbours i, i + 4, ...), so no shuffle per neighbour and no sum waits on
/// another; the 4 lanes are added at the end.
GF_TARGET_AVX2_PATHS void sumsAvx2Fast(const float* xyz, const std::int32_t* row, int k,
                                       std::size_t query, Moments* s) {
  const float* const q = xyz + 3 * query;
  const __m256d qx = _mm256_set1_pd(q[0]), qy = _mm256_set1_pd(q[1]), qz = _mm256_set1_pd(q[2]);
  const __m128i xyz_only = _mm_setr_epi32(-1, -1, -1, 0);  // no read past a point's z
  __m256d sx = _mm256_setzero_pd(), sy = sx, sz = sx, sxx = sx, sxy = sx, sxz = sx, syy = sx,
          syz = sx, szz = sx;
  int j = 0;
  for (; j + 4 <= k; j += 4) {
    __m128 p0 = _mm_maskload_ps(xyz + 3 * static_cast<std::size_t>(row[j]), xyz_only);
    __m128 p1 = _mm_maskload_ps(xyz + 3 * static_cast<std::size_t>(row[j + 1]), xyz_only);
    __m128 p2 = _mm_maskload_ps(xyz + 3 * static_cast<std::size_t>(row[j + 2]), xyz_only);
    __m128 p3 = _mm_maskload_ps(xyz + 3 * static_cast<std::size_t>(row[j + 3]), xyz_only);
    _MM_TRANSPOSE4_PS(p0, p1, p2, p3);  // p0: the four x, p1: y, p2: z
    const __m256d dx = _mm256_sub_pd(_mm256_cvtps_pd(p0), qx);
    const __m256d dy = _mm256_sub_pd(_mm256_cvtps_pd(p1), qy);
    const __m256d dz = _mm256_sub_pd(_mm256_cvtps_pd(p2), qz);
    sx = _mm256_add_pd(sx, dx);
    sy = _mm256_add_pd(sy, dy);
    sz = _mm256_add_pd(sz, dz);
    sxx = _mm256_add_pd(sxx, _mm256_mul_pd(dx, dx));
    sxy = _mm256_add_pd(sxy, _mm256_mul_pd(dx, dy));
    sxz = _mm256_add_pd(sxz, _mm256_mul_pd(dx, dz));
    syy = _mm256_add_pd(syy, _mm256_mul_pd(dy, dy));
    syz = _mm256_add_pd(syz, _mm256_mul_pd(dy, dz));
    szz = _mm256_add_pd(szz, _mm256_mul_pd(dz, dz));
  }
  alignas(16) double r[10];
  _mm_store_pd(r, laneSums2(sx, sy));
  _mm_store_pd(r + 2, laneSums2(sz, sxx));
  _mm_store_pd(r + 4, laneSums2(sxy, sxz));
  _mm_store_pd(r + 6, laneSums2(syy, syz));
  _mm_store_pd(r + 8, laneSums2(szz, _mm256_setzero_pd()));
  Moments m{r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], 0};
  const double ox = q[0], oy = q[1], oz = q[2];
  for (; j < k; ++j) {  // the last k mod 4
    const float* p = xyz + 3 * static_cast<std::size_t>(row[j]);
    m.add(p[0] - ox, p[1] - oy, p[2] - oz);
  }
  m.m = k;
  *s = m;
}

#pragma GCC diagnostic pop

bool haveAvx2() {
  static const bool has = simd::avx2::cpuHasAvx2();
  return has && simd::allows(simd::Level::kAvx2);
}

#else

bool haveAvx2() { return false; }

#endif  // GF_HAVE_AVX2_PATHS

#if GF_HAVE_NEON_PATHS

// NEON (aarch64): the nine sums in four registers of two doubles, [sx sy], [sxx sxy],
// [sxz syz], [syy szz], and sz in a scalar; each lane added to in neighbour order as in
// sumsScalar(), products not fused (the same bits).

/// sumsScalar() of a full row (k valid entries), the same bits.
void sumsNeon(const float* xyz, const std::int32_t* row, int k, std::size_t query, Moments* s) {
  using simd::neon::opaque;
  const float* q = xyz + 3 * query;
  const float64x2_t oxy = vcvt_f64_f32(vld1_f32(q));
  const double oz = q[2];
  float64x2_t s_xy = vdupq_n_f64(0.0), s_xx_xy = s_xy, s_xz_yz = s_xy, s_yy_zz = s_xy;
  double sz = 0.0;
  for (int j = 0; j < k; ++j) {
    const float* p = xyz + 3 * static_cast<std::size_t>(row[j]);
    const float64x2_t d = vsubq_f64(vcvt_f64_f32(vld1_f32(p)), oxy);  // dx dy
    const double dz = p[2] - oz;
    const float64x2_t yz = vsetq_lane_f64(dz, vdupq_laneq_f64(d, 1), 1);  // dy dz
    s_xy = vaddq_f64(s_xy, d);
    sz += dz;
    s_xx_xy = vaddq_f64(s_xx_xy, opaque(vmulq_laneq_f64(d, d, 0)));  // dx dx, dy dx
    s_xz_yz = vaddq_f64(s_xz_yz, opaque(vmulq_n_f64(d, dz)));        // dx dz, dy dz
    s_yy_zz = vaddq_f64(s_yy_zz, opaque(vmulq_f64(yz, yz)));         // dy dy, dz dz
  }
  *s = Moments{vgetq_lane_f64(s_xy, 0),
               vgetq_lane_f64(s_xy, 1),
               sz,
               vgetq_lane_f64(s_xx_xy, 0),
               vgetq_lane_f64(s_xx_xy, 1),
               vgetq_lane_f64(s_xz_yz, 0),
               vgetq_lane_f64(s_yy_zz, 0),
               vgetq_lane_f64(s_xz_yz, 1),
               vgetq_lane_f64(s_yy_zz, 1),
               k};
}

bool haveNeon() { return simd::allows(simd::Level::kNeon); }

#endif  // GF_HAVE_NEON_PATHS

/// Which code computes the sums: chosen once per call of the public functions (the SIMD level
/// in force can change between calls: tests run every level in one process).
enum class SumsPath { kScalar, kNeon, kAvx2, kAvx512 };

SumsPath sumsPath() {
  if (haveAvx512()) return SumsPath::kAvx512;
  if (haveAvx2()) return SumsPath::kAvx2;
#if GF_HAVE_NEON_PATHS
  if (haveNeon()) return SumsPath::kNeon;
#endif
  return SumsPath::kScalar;
}

/// Centred covariance of a neighbourhood and its trace: covarianceOf() (pca_cpu_gpu_common.h).
using Covariance = NeighborhoodCovariance;

/// Eigen's closed-form solver on a valid covariance.
inline void eigenPca(const Covariance& c, PointPca* out) {
  PointPca& r = *out;
  Eigen::Matrix3d cov;
  cov << c.xx, c.xy, c.xz, c.xy, c.yy, c.yz, c.xz, c.yz, c.zz;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  Eigen::Vector3d ev = es.eigenvalues().cwiseMax(0.0);  // ascending; rounding can go < 0
  const double sum = ev.sum();
  if (!(sum > 0.0)) return;
  ev /= sum;
  const Eigen::Vector3d nv = es.eigenvectors().col(0);
  if (!nv.allFinite()) return;
  for (int d = 0; d < 3; ++d) {
    r.normal[d] = static_cast<float>(nv[d]);
    r.eigen[d] = static_cast<float>(ev[d]);
  }
  r.valid = true;
}

/// Covariance from the sums, then Eigen's closed-form solver.
inline void finish(const Moments& s, PointPca* out) {
  *out = PointPca();
  Covariance c;
  if (covarianceOf(s, &c)) eigenPca(c, out);
}

/// The neighbourhood sums of row `row` (k entries, -1 = none) around the point `query`.
inline void sumsOf(const float* xyz, const std::int32_t* row, int k, std::size_t query,
                   SumsPath path, Moments* s) {
  const bool full = row[k - 1] >= 0;  // a full row (rows end at their first -1)
#if GF_HAVE_AVX512
  if (path == SumsPath::kAvx512 && full) {
    sumsAvx512(xyz, row, k, query, s);
    return;
  }
#endif
#if GF_HAVE_AVX2_PATHS
  if (path == SumsPath::kAvx2 && full) {
    sumsAvx2(xyz, row, k, query, s);
    return;
  }
#endif
#if GF_HAVE_NEON_PATHS
  if (path == SumsPath::kNeon && full) {
    sumsNeon(xyz, row, k, query, s);
    return;
  }
#endif
  (void)path;
  (void)full;
  sumsScalar(xyz, row, k, query, s);
}

// ---- Candidate decision without the eigen solver where it is certain.
//
// The reference decision is isCandidatePca() on eigenPca()'s float output. Eigen's closed form
// (atan2/cos/sin) is two thirds of the PCA time. Here the eigenvalues come from the
// characteristic polynomial instead, and the decision is taken only when every one of its
// margins is far beyond the error of both computations; otherwise eigenPca() decides.
//
// Error budget, in units of the trace: Eigen's closed form errs by about sqrt(eps) ~ 1.5e-8 at
// worst (near a double root), the Newton/quadratic solution below by about as much, the float
// rounding of the stored values by 6e-8 relative. CandidateTest::eigen_tol (default 1e-6) covers
// all of them with a factor > 10.
//
// The normal only matters when the point is certainly flat. Flat means s2 >= 2 s3 and
// 2 s2 >= s1 + s3 (s = sqrt of the eigenvalues, descending), i.e. lambda1 >= 4 lambda0 and
// lambda1 >= lambda2 / 4 >= trace / 12, so the gap lambda1 - lambda0 >= trace / 16: the
// eigenvector of lambda0 is well conditioned (error <= ~16x the eigenvalue error) and
// normalTol() = 100 eigen_tol covers both normals.

/// Decision margin of the normal-z test beyond the errors (see above) [1].
inline double normalTol(double eigen_tol) { return 100.0 * eigen_tol; }

/// 1 / 0 when the candidate decision is certain from the covariance alone, -1 when the exact
/// path must decide. Counts the early rejects and fast decisions in `counts`.
inline int fastCandidate(const Covariance& c, const CandidateTest& t, CandidateCounts* counts) {
  const double tr = c.trace;
  // Early reject. With n the unit normal and lambda0 <= lambda1 <= lambda2:
  // c_zz = lambda0 n_z^2 + (the rest, <= lambda2 (1 - n_z^2)) <= lambda0 + trace (1 - n_z^2).
  // A candidate has n_z^2 >= min_abs_nz^2 and lambda0 <= trace / 9 (lambda1 >= 4 lambda0 and
  // lambda2 >= lambda1), so c_zz <= trace (1/9 + 1 - min_abs_nz^2). Slack 1e-4 for rounding.
  const double nz_lo = std::max(0.0, t.min_abs_nz - 1e-4);
  if (c.zz > (1.0 / 9.0 + 1.0 - nz_lo * nz_lo + 1e-4) * tr) {
    ++counts->early;
    return 0;
  }
  // Eigenvalues of B = C - (trace/3) I (trace 0: better conditioned near a triple root):
  // det(x I - B) = x^3 - a x - det(B), a = sum of B_ij^2 / 2 >= 0.
  const double m = tr / 3.0;
  const double b00 = c.xx - m, b11 = c.yy - m, b22 = c.zz - m;
  const double a =
      0.5 * (b00 * b00 + b11 * b11 + b22 * b22) + c.xy * c.xy + c.xz * c.xz + c.yz * c.yz;
  const double det = b00 * (b11 * b22 - c.yz * c.yz) - c.xy * (c.xy * b22 - c.yz * c.xz) +
                     c.xz * (c.xy * c.yz - b11 * c.xz);
  // Smallest root x0 by Newton from a lower bound of it (below; else from x = -m, lambda = 0 <=
  // lambda0 as C is PSD). p is increasing and concave left of x0 (p'' = 6x < 0 and x0 <= -sqrt(a/3)
  // < 0), so the iterates rise monotonically towards x0 and never pass it. Once the steps are
  // small, p(x + w) >= 0 proves x0 <= x + wb (p < 0 on [x, x0)): x0 is then known to wb = 1e-8
  // trace, far inside the margins.
  const double wb = 1e-8 * tr;
  // The start: lambda0 = det(C) / (lambda1 lambda2) and lambda1 lambda2 <= (trace / 2)^2, so
  // lambda0 >= 4 det(C) / trace^2, tight for flat ground (lambda1 ~ lambda2), so fewer steps.
  // Rounding may put it past x0 (p > 0 there): then lambda = 0.
  const double det_c = c.xx * (c.yy * c.zz - c.yz * c.yz) - c.xy * (c.xy * c.zz - c.yz * c.xz) +
                       c.xz * (c.xy * c.yz - c.yy * c.xz);
  double x = 4.0 * std::max(0.0, det_c) / (tr * tr) - m;
  if (!((x * x - a) * x - det <= 0.0)) x = -m;
  bool converged = false;
  for (int it = 0; it < 16; ++it) {
    const double p = (x * x - a) * x - det, dp = 3.0 * x * x - a;
    if (!(dp > 0.0)) break;
    const double step = p / dp;
    x -= step;
    if (std::abs(step) <= 1e-5 * tr) {
      const double y = x + wb;
      if ((y * y - a) * y - det >= 0.0) {
        x += 0.5 * wb;  // the middle of [x, x + wb]
        converged = true;
        break;
      }
    }
  }
  if (!converged) return -1;
  // The other two from p(x) = (x - x0)(x^2 + x0 x + x0^2 - a).
  const double disc = std::sqrt(std::max(0.0, 4.0 * a - 3.0 * x * x));
  const double inv = 1.0 / tr;
  const double e0 = std::max(0.0, (x + m) * inv);
  const double e1 = std::max(0.0, ((-x - disc) * 0.5 + m) * inv);
  const double e2 = std::max(0.0, ((-x + disc) * 0.5 + m) * inv);
  // Intervals of s = sqrt(normalised eigenvalue) that hold both this and Eigen's result.
  const double tol = t.eigen_tol;
  const double lo0 = std::sqrt(std::max(0.0, e0 - tol)), hi0 = std::sqrt(e0 + tol);
  const double lo1 = std::sqrt(std::max(0.0, e1 - tol)), hi1 = std::sqrt(e1 + tol);
  const double lo2 = std::sqrt(std::max(0.0, e2 - tol)), hi2 = std::sqrt(e2 + tol);
  // isCandidatePca(): s1 = s(lambda2) > 0 and planar >= linear (2 s2 - s1 - s3 >= 0),
  // planar >= scatter (s2 - 2 s3 >= 0), planar >= min_planarity (s2 - s3 - mp s1 >= 0).
  if (!(lo2 > 0.0)) return -1;
  const double mp = t.min_planarity;
  const double a_lo = 2.0 * lo1 - hi2 - hi0, a_hi = 2.0 * hi1 - lo2 - lo0;
  const double b_lo = lo1 - 2.0 * hi0, b_hi = hi1 - 2.0 * lo0;
  const double c_lo = lo1 - hi0 - (mp >= 0 ? mp * hi2 : mp * lo2);
  const double c_hi = hi1 - lo0 - (mp >= 0 ? mp * lo2 : mp * hi2);
  if (a_hi < 0.0 || b_hi < 0.0 || c_hi < 0.0) {
    ++counts->fast;
    return 0;  // certainly not flat
  }
  if (!(a_lo > 0.0 && b_lo > 0.0 && c_lo > 0.0)) return -1;
  // Certainly flat. The normal: the largest cross product of two rows of C - lambda0 I.
  if (!(t.min_abs_nz > 0.0)) {
    ++counts->fast;
    return 1;  // |n_z| >= min_abs_nz always holds
  }
  const double l0 = x + m;
  const double r0[3] = {c.xx - l0, c.xy, c.xz}, r1[3] = {c.xy, c.yy - l0, c.yz},
               r2[3] = {c.xz, c.yz, c.zz - l0};
  auto cross = [](const double* u, const double* v, double* w) {
    w[0] = u[1] * v[2] - u[2] * v[1];
    w[1] = u[2] * v[0] - u[0] * v[2];
    w[2] = u[0] * v[1] - u[1] * v[0];
  };
  double w[3][3];
  cross(r0, r1, w[0]);
  cross(r0, r2, w[1]);
  cross(r1, r2, w[2]);
  int best = 0;
  double best_n = -1.0;
  for (int j = 0; j < 3; ++j) {
    const double n2 = w[j][0] * w[j][0] + w[j][1] * w[j][1] + w[j][2] * w[j][2];
    if (n2 > best_n) {
      best_n = n2;
      best = j;
    }
  }
  if (!(best_n > 0.0)) return -1;
  const double nz = std::abs(w[best][2]) / std::sqrt(best_n);
  const double margin = nz - t.min_abs_nz, ntol = normalTol(tol);
  if (margin >= ntol) {
    ++counts->fast;
    return 1;
  }
  if (margin <= -ntol) {
    ++counts->fast;
    return 0;
  }
  return -1;
}

/// The variance coordinates on a lattice hide (CandidateTest::lattice_var) back in `c`.
inline void addLattice(const CandidateTest& t, Covariance* c) {
  const double* v = t.lattice_var;
  if (v[0] == 0.0 && v[1] == 0.0 && v[2] == 0.0) return;  // the usual case: bits unchanged
  c->xx += v[0];
  c->yy += v[1];
  c->zz += v[2];
  c->trace += v[0] + v[1] + v[2];
}

/// Candidate flag of one neighbourhood: fastCandidate() where certain, else the reference
/// (sums in list order, Eigen's solver, isCandidatePca()).
inline std::uint8_t candidateOne(const float* xyz, const std::int32_t* row, int k,
                                 std::size_t query, SumsPath path, const CandidateTest& t,
                                 CandidateCounts* counts) {
  Moments s;
  Covariance c;
  bool fast_tried = false;  // fastCandidate() already undecided on the fast sums
#if GF_HAVE_AVX512 || GF_HAVE_AVX2_PATHS
  if (!t.exact_only && (path == SumsPath::kAvx512 || path == SumsPath::kAvx2) && k >= 3 &&
      row[k - 1] >= 0) {
#if GF_HAVE_AVX512
    if (path == SumsPath::kAvx512) sumsAvx512Fast(xyz, row, k, query, &s);
#endif
#if GF_HAVE_AVX2_PATHS
    if (path == SumsPath::kAvx2) sumsAvx2Fast(xyz, row, k, query, &s);
#endif
    // Another addition order moves the covariance by <= ~2 k eps (mean squared offset from
    // the query); trusted when that is < 1e-4 of the trace (so < 3e-10 trace, far inside the
    // margins) and away from the reference's validity threshold. All squares exactly 0 means
    // every offset is 0 (a float difference squared in double cannot underflow): the
    // reference's trace is 0 too.
    if (s.sxx == 0.0 && s.syy == 0.0 && s.szz == 0.0) {
      ++counts->invalid;
      return 0;
    }
    if (covarianceOf(s, &c) && c.trace > 1e-11 && s.sxx + s.syy + s.szz <= 1e4 * s.m * c.trace) {
      addLattice(t, &c);
      const int d = fastCandidate(c, t, counts);
      if (d >= 0) return static_cast<std::uint8_t>(d);
      fast_tried = true;
    }
  }
#endif
  // The reference sums (list order).
  sumsOf(xyz, row, k, query, path, &s);
  if (!covarianceOf(s, &c)) {
    ++counts->invalid;
    return 0;
  }
  addLattice(t, &c);
  if (!t.exact_only && !fast_tried) {
    const int d = fastCandidate(c, t, counts);
    if (d >= 0) return static_cast<std::uint8_t>(d);
  }
  ++counts->exact;
  PointPca r;
  eigenPca(c, &r);
  return isCandidatePca(r, t.min_planarity, t.min_abs_nz);
}

/// PCA of one neighbourhood: `row` (k entries, -1 = none) around the point `query`.
inline void pcaOne(const float* xyz, const std::int32_t* row, int k, std::size_t query,
                   SumsPath path, PointPca* out) {
  Moments s;
  sumsOf(xyz, row, k, query, path, &s);
  finish(s, out);
}

}  // namespace

void computeRowsPca(const float* xyz, const std::int32_t* indices, int k, const std::uint32_t* rows,
                    std::size_t count, PointPca* out) {
  const std::size_t kk = static_cast<std::size_t>(k);
  const SumsPath path = sumsPath();
  for (std::size_t j = 0; j < count; ++j) {
    const std::size_t r = rows[j];
    pcaOne(xyz, indices + r * kk, k, r, path, &out[r]);
  }
}

void computeOrderedRowsPca(const float* xyz, const std::int32_t* rows, int k,
                           const std::uint32_t* query, std::size_t count, PointPca* out) {
  const std::size_t kk = static_cast<std::size_t>(k);
  const SumsPath path = sumsPath();
  for (std::size_t j = 0; j < count; ++j) {
    pcaOne(xyz, rows + j * kk, k, query[j], path, &out[query[j]]);
  }
}

void computeNeighborhoodPca(const float* xyz, const NeighborLists& lists, int threads,
                            std::vector<PointPca>* out) {
  const std::size_t n = lists.points;
  const int k = lists.k;
  out->resize(n);
  if (n == 0 || k <= 0) return;
  const SumsPath path = sumsPath();
  const int all = resolveThreads(threads);
  const int nt = static_cast<int>(std::min<std::size_t>(all, n / 1024 + 1));
#pragma omp parallel for num_threads(nt) schedule(static, 2048)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
    pcaOne(xyz, &lists.indices[static_cast<std::size_t>(i) * k], k, static_cast<std::size_t>(i),
           path, &(*out)[i]);
  }
}

bool isFlatPca(const PointPca& r, double min_planarity) {
  // sigma_i = sqrt(lambda_i), sigma_1 >= sigma_2 >= sigma_3: linearity (s1 - s2)/s1, planarity
  // (s2 - s3)/s1, scattering s3/s1.
  const double s1 = std::sqrt(static_cast<double>(r.eigen[2]));
  const double s2 = std::sqrt(static_cast<double>(r.eigen[1]));
  const double s3 = std::sqrt(static_cast<double>(r.eigen[0]));
  if (!(s1 > 0.0)) return false;
  const double linear = (s1 - s2) / s1, planar = (s2 - s3) / s1, scatter = s3 / s1;
  return planar >= linear && planar >= scatter && planar >= min_planarity;
}

bool isCandidatePca(const PointPca& r, double min_planarity, double min_abs_nz) {
  return r.valid && isFlatPca(r, min_planarity) && std::abs(r.normal[2]) >= min_abs_nz;
}

void computeRowsCandidates(const float* xyz, const std::int32_t* indices, int k,
                           const std::uint32_t* rows, std::size_t count, const CandidateTest& t,
                           std::uint8_t* candidate, CandidateCounts* counts) {
  const std::size_t kk = static_cast<std::size_t>(k);
  const SumsPath path = sumsPath();
  for (std::size_t j = 0; j < count; ++j) {
    const std::size_t r = rows[j];
    candidate[r] = candidateOne(xyz, indices + r * kk, k, r, path, t, counts);
  }
}

void computeOrderedRowsCandidates(const float* xyz, const std::int32_t* rows, int k,
                                  const std::uint32_t* query, std::size_t count,
                                  const CandidateTest& t, std::uint8_t* candidate,
                                  CandidateCounts* counts) {
  const std::size_t kk = static_cast<std::size_t>(k);
  const SumsPath path = sumsPath();
  for (std::size_t j = 0; j < count; ++j) {
    candidate[query[j]] = candidateOne(xyz, rows + j * kk, k, query[j], path, t, counts);
  }
}

void computeNeighborhoodCandidates(const float* xyz, const NeighborLists& lists, int threads,
                                   const CandidateTest& t, std::uint8_t* candidate,
                                   CandidateCounts* counts) {
  const std::size_t n = lists.points;
  const int k = lists.k;
  CandidateCounts total;
  if (n > 0 && k > 0) {
    const SumsPath path = sumsPath();
    const int all = resolveThreads(threads);
    const int nt = static_cast<int>(std::min<std::size_t>(all, n / 1024 + 1));
    std::size_t invalid = 0, early = 0, fast = 0, exact = 0;
#pragma omp parallel for num_threads(nt) schedule(static, 2048) \
    reduction(+ : invalid, early, fast, exact)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
      CandidateCounts c;
      candidate[i] = candidateOne(xyz, &lists.indices[static_cast<std::size_t>(i) * k], k,
                                  static_cast<std::size_t>(i), path, t, &c);
      invalid += c.invalid;
      early += c.early;
      fast += c.fast;
      exact += c.exact;
    }
    total = CandidateCounts{invalid, early, fast, exact};
  }
  if (counts) *counts = total;
}

}  // namespace ground_filter
