// Stage "pca" of the normal filter: covariance of every K neighbourhood and its eigen
// decomposition, in double. With AVX-512 the nine sums of a neighbourhood are kept in two
// registers (lane by lane the same additions in the same order, products not fused: the same
// bits as the scalar code). One neighbourhood per lane with gathers was 1.5x slower on Zen 4.

#include "normal/neighborhood_pca.h"

#include <omp.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cstdint>

#include "neighbors/avx512_common.h"

namespace ground_filter {

namespace {

/// Sums of a neighbourhood's offsets from its query point and of their products.
struct Moments {
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  int m = 0;  // neighbours summed
};

/// One pass over the neighbours, in double. The offsets are small (a neighbourhood, not 80 m
/// ranges), so centring afterwards loses nothing measurable and the neighbours are read once.
inline void sumsScalar(const float* xyz, const std::int32_t* row, int k, std::size_t query,
                       Moments* s) {
  const double ox = xyz[3 * query], oy = xyz[3 * query + 1], oz = xyz[3 * query + 2];
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  int m = 0;
  for (; m < k && row[m] >= 0; ++m) {
    const float* p = xyz + 3 * static_cast<std::size_t>(row[m]);
    const double dx = p[0] - ox, dy = p[1] - oy, dz = p[2] - oz;
    sx += dx;
    sy += dy;
    sz += dz;
    sxx += dx * dx;
    sxy += dx * dy;
    sxz += dx * dz;
    syy += dy * dy;
    syz += dy * dz;
    szz += dz * dz;
  }
  *s = Moments{sx, sy, sz, sxx, sxy, sxz, syy, syz, szz, m};
}

#if GF_HAVE_AVX512

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

using simd::opaque;

/// sumsScalar() of a full row (k valid entries): lanes [sx sy sz - - - - -] and
/// [sxx sxy sxz syy syz szz - -], each lane added to in neighbour order.
GF_TARGET_AVX512 void sumsAvx512(const float* xyz, const std::int32_t* row, int k,
                                 std::size_t query, Moments* s) {
  const __mmask16 three = 0x7;
  const __m512d o = _mm512_cvtps_pd(_mm256_castps128_ps256(
      _mm_castsi128_ps(_mm512_castsi512_si128(_mm512_maskz_loadu_epi32(three, xyz + 3 * query)))));
  const __m512i pa = _mm512_set_epi64(3, 3, 2, 1, 1, 0, 0, 0);  // dx dx dx dy dy dz
  const __m512i pb = _mm512_set_epi64(3, 3, 2, 2, 1, 2, 1, 0);  // dx dy dz dy dz dz
  __m512d s1 = _mm512_setzero_pd(), s2 = _mm512_setzero_pd();
  for (int j = 0; j < k; ++j) {
    const float* p = xyz + 3 * static_cast<std::size_t>(row[j]);
    const __m512d v = _mm512_cvtps_pd(_mm256_castps128_ps256(
        _mm_castsi128_ps(_mm512_castsi512_si128(_mm512_maskz_loadu_epi32(three, p)))));
    const __m512d d = _mm512_maskz_sub_pd(0x7, v, o);  // dx dy dz 0 ...
    s1 = _mm512_add_pd(s1, d);
    const __m512d prod =
        opaque(_mm512_mul_pd(_mm512_permutexvar_pd(pa, d), _mm512_permutexvar_pd(pb, d)));
    s2 = _mm512_add_pd(s2, prod);
  }
  alignas(64) double a[8], b[8];
  _mm512_store_pd(a, s1);
  _mm512_store_pd(b, s2);
  *s = Moments{a[0], a[1], a[2], b[0], b[1], b[2], b[3], b[4], b[5], k};
}

#pragma GCC diagnostic pop

bool haveAvx512() {
  static const bool has = simd::cpuHasAvx512();
  return has;
}

#else

bool haveAvx512() { return false; }

#endif  // GF_HAVE_AVX512

/// Covariance from the sums, then Eigen's closed-form solver.
inline void finish(const Moments& s, PointPca* out) {
  PointPca& r = *out;
  r = PointPca();
  if (s.m < 3) return;
  const double inv = 1.0 / s.m, mx = s.sx * inv, my = s.sy * inv, mz = s.sz * inv;
  const double cxx = s.sxx * inv - mx * mx, cxy = s.sxy * inv - mx * my,
               cxz = s.sxz * inv - mx * mz, cyy = s.syy * inv - my * my,
               cyz = s.syz * inv - my * mz, czz = s.szz * inv - mz * mz;
  const double trace = cxx + cyy + czz;
  if (!(trace > 1e-12)) return;  // all neighbours (nearly) the same point
  Eigen::Matrix3d cov;
  cov << cxx, cxy, cxz, cxy, cyy, cyz, cxz, cyz, czz;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  Eigen::Vector3d ev = es.eigenvalues().cwiseMax(0.0);  // ascending; rounding can go < 0
  const double sum = ev.sum();
  if (!(sum > 0.0)) return;
  ev /= sum;
  const Eigen::Vector3d nv = es.eigenvectors().col(0);
  if (!nv.allFinite()) return;
  for (int c = 0; c < 3; ++c) {
    r.normal[c] = static_cast<float>(nv[c]);
    r.eigen[c] = static_cast<float>(ev[c]);
  }
  r.valid = true;
}

/// PCA of one neighbourhood: `row` (k entries, -1 = none) around the point `query`.
inline void pcaOne(const float* xyz, const std::int32_t* row, int k, std::size_t query, bool avx512,
                   PointPca* out) {
  Moments s;
#if GF_HAVE_AVX512
  if (avx512 && row[k - 1] >= 0) {  // a full row (rows end at their first -1)
    sumsAvx512(xyz, row, k, query, &s);
  } else {
    sumsScalar(xyz, row, k, query, &s);
  }
#else
  (void)avx512;
  sumsScalar(xyz, row, k, query, &s);
#endif
  finish(s, out);
}

}  // namespace

void computeRowsPca(const float* xyz, const std::int32_t* indices, int k, const std::uint32_t* rows,
                    std::size_t count, PointPca* out) {
  const std::size_t kk = static_cast<std::size_t>(k);
  const bool avx512 = haveAvx512();
  for (std::size_t j = 0; j < count; ++j) {
    const std::size_t r = rows[j];
    pcaOne(xyz, indices + r * kk, k, r, avx512, &out[r]);
  }
}

void computeOrderedRowsPca(const float* xyz, const std::int32_t* rows, int k,
                           const std::uint32_t* query, std::size_t count, PointPca* out) {
  const std::size_t kk = static_cast<std::size_t>(k);
  const bool avx512 = haveAvx512();
  for (std::size_t j = 0; j < count; ++j) {
    pcaOne(xyz, rows + j * kk, k, query[j], avx512, &out[query[j]]);
  }
}

void computeNeighborhoodPca(const float* xyz, const NeighborLists& lists, int threads,
                            std::vector<PointPca>* out) {
  const std::size_t n = lists.points;
  const int k = lists.k;
  out->resize(n);
  if (n == 0 || k <= 0) return;
  const bool avx512 = haveAvx512();
  const int all = threads > 0 ? threads : omp_get_num_procs();
  const int nt = static_cast<int>(std::min<std::size_t>(all, n / 1024 + 1));
#pragma omp parallel for num_threads(nt) schedule(static, 2048)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
    pcaOne(xyz, &lists.indices[static_cast<std::size_t>(i) * k], k, static_cast<std::size_t>(i),
           avx512, &(*out)[i]);
  }
}

}  // namespace ground_filter
