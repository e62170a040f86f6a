// Stage "pca" of the normal filter: covariance of every K neighbourhood and its eigen
// decomposition. The sums are formed per neighbour in list order, in double, without fused
// multiply-adds, so the AVX-512 path (8 neighbourhoods at a time, one per lane) gives the same
// bits as the scalar one.

#include "ground_filter/neighborhood_pca.h"

#include <omp.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cstdint>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define GF_PCA_HAVE_AVX512 1
#define GF_PCA_TARGET_AVX512 __attribute__((target("avx512f")))
#else
#define GF_PCA_HAVE_AVX512 0
#endif

namespace ground_filter {

namespace {

/// Sums of one neighbourhood's offsets from its query point and of their products.
struct Moments {
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  int m = 0;  // neighbours summed
};

/// One pass over the neighbours, in double. The offsets are small (a neighbourhood, not 80 m
/// ranges), so centring afterwards loses nothing measurable and the neighbours are read once.
Moments accumulate(const float* xyz, const std::int32_t* row, int k, std::size_t query) {
  Moments s;
  const double ox = xyz[3 * query], oy = xyz[3 * query + 1], oz = xyz[3 * query + 2];
  for (; s.m < k && row[s.m] >= 0; ++s.m) {
    const float* p = xyz + 3 * static_cast<std::size_t>(row[s.m]);
    const double dx = p[0] - ox, dy = p[1] - oy, dz = p[2] - oz;
    s.sx += dx;
    s.sy += dy;
    s.sz += dz;
    s.sxx += dx * dx;
    s.sxy += dx * dy;
    s.sxz += dx * dz;
    s.syy += dy * dy;
    s.syz += dy * dz;
    s.szz += dz * dz;
  }
  return s;
}

/// Covariance from the moments, then Eigen's closed-form solver.
void finish(const Moments& s, PointPca* out) {
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

#if GF_PCA_HAVE_AVX512

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

/// Keeps the compiler from fusing a product into the following addition.
GF_PCA_TARGET_AVX512 inline __m512d opaque(__m512d v) {
  asm("" : "+v"(v));
  return v;
}

/// accumulate() for the 8 queries `q[0..8)` (row r = query r), one per double lane.
GF_PCA_TARGET_AVX512 void accumulate8(const float* xyz, const std::int32_t* indices, int k,
                                      const std::uint64_t* q, Moments* out) {
  alignas(64) double o[3][8];
  alignas(64) std::int64_t row_off[8];
  for (int l = 0; l < 8; ++l) {
    for (int c = 0; c < 3; ++c) o[c][l] = xyz[3 * q[l] + c];
    row_off[l] = static_cast<std::int64_t>(q[l] * static_cast<std::uint64_t>(k)) * 4;
  }
  const __m512d ox = _mm512_load_pd(o[0]), oy = _mm512_load_pd(o[1]), oz = _mm512_load_pd(o[2]);
  __m512i off = _mm512_load_si512(row_off);
  const __m512i four = _mm512_set1_epi64(4), zero = _mm512_setzero_si512();
  const __m512i one = _mm512_set1_epi64(1);
  __m512d sx = _mm512_setzero_pd(), sy = sx, sz = sx, sxx = sx, sxy = sx, sxz = sx, syy = sx,
          syz = sx, szz = sx;
  __m512i m = zero;
  __mmask8 act = 0xff;
  for (int j = 0; j < k && act; ++j) {
    const __m256i idx32 = _mm512_mask_i64gather_epi32(_mm256_setzero_si256(), act, off, indices, 1);
    const __m512i idx = _mm512_cvtepi32_epi64(idx32);
    act = _mm512_mask_cmpge_epi64_mask(act, idx, zero);  // a row ends at its first -1
    const __m512i pos = _mm512_add_epi64(_mm512_slli_epi64(idx, 1), idx);  // 3 * idx
    const __m256 zf = _mm256_setzero_ps();
    const __m512d px = _mm512_cvtps_pd(_mm512_mask_i64gather_ps(zf, act, pos, xyz, 4));
    const __m512d py = _mm512_cvtps_pd(_mm512_mask_i64gather_ps(zf, act, pos, xyz + 1, 4));
    const __m512d pz = _mm512_cvtps_pd(_mm512_mask_i64gather_ps(zf, act, pos, xyz + 2, 4));
    const __m512d dx = _mm512_sub_pd(px, ox), dy = _mm512_sub_pd(py, oy),
                  dz = _mm512_sub_pd(pz, oz);
    sx = _mm512_mask_add_pd(sx, act, sx, dx);
    sy = _mm512_mask_add_pd(sy, act, sy, dy);
    sz = _mm512_mask_add_pd(sz, act, sz, dz);
    sxx = _mm512_mask_add_pd(sxx, act, sxx, opaque(_mm512_mul_pd(dx, dx)));
    sxy = _mm512_mask_add_pd(sxy, act, sxy, opaque(_mm512_mul_pd(dx, dy)));
    sxz = _mm512_mask_add_pd(sxz, act, sxz, opaque(_mm512_mul_pd(dx, dz)));
    syy = _mm512_mask_add_pd(syy, act, syy, opaque(_mm512_mul_pd(dy, dy)));
    syz = _mm512_mask_add_pd(syz, act, syz, opaque(_mm512_mul_pd(dy, dz)));
    szz = _mm512_mask_add_pd(szz, act, szz, opaque(_mm512_mul_pd(dz, dz)));
    m = _mm512_mask_add_epi64(m, act, m, one);
    off = _mm512_add_epi64(off, four);
  }
  alignas(64) double s[9][8];
  alignas(64) std::int64_t mm[8];
  _mm512_store_pd(s[0], sx);
  _mm512_store_pd(s[1], sy);
  _mm512_store_pd(s[2], sz);
  _mm512_store_pd(s[3], sxx);
  _mm512_store_pd(s[4], sxy);
  _mm512_store_pd(s[5], sxz);
  _mm512_store_pd(s[6], syy);
  _mm512_store_pd(s[7], syz);
  _mm512_store_pd(s[8], szz);
  _mm512_store_si512(mm, m);
  for (int l = 0; l < 8; ++l) {
    Moments& r = out[l];
    r.sx = s[0][l];
    r.sy = s[1][l];
    r.sz = s[2][l];
    r.sxx = s[3][l];
    r.sxy = s[4][l];
    r.sxz = s[5][l];
    r.syy = s[6][l];
    r.syz = s[7][l];
    r.szz = s[8][l];
    r.m = static_cast<int>(mm[l]);
  }
}

#pragma GCC diagnostic pop

bool useAvx512() {
  static const bool has = __builtin_cpu_supports("avx512f");
  return has;
}

#else

bool useAvx512() { return false; }

#endif  // GF_PCA_HAVE_AVX512

/// PCA of `count` rows: row j is rows[j], or first + j when rows is null.
void pcaRows(const float* xyz, const std::int32_t* indices, int k, const std::uint32_t* rows,
             std::size_t first, std::size_t count, PointPca* out) {
  auto row_of = [&](std::size_t j) -> std::uint64_t { return rows ? rows[j] : first + j; };
  std::size_t j = 0;
#if GF_PCA_HAVE_AVX512
  if (useAvx512()) {
    std::uint64_t q[8];
    Moments s[8];
    for (; j + 8 <= count; j += 8) {
      for (int l = 0; l < 8; ++l) q[l] = row_of(j + l);
      accumulate8(xyz, indices, k, q, s);
      for (int l = 0; l < 8; ++l) finish(s[l], &out[q[l]]);
    }
  }
#endif
  for (; j < count; ++j) {
    const std::uint64_t r = row_of(j);
    finish(accumulate(xyz, indices + r * static_cast<std::uint64_t>(k), k, r), &out[r]);
  }
}

}  // namespace

void computeRowsPca(const float* xyz, const std::int32_t* indices, int k, const std::uint32_t* rows,
                    std::size_t count, PointPca* out) {
  pcaRows(xyz, indices, k, rows, 0, count, out);
}

void computeNeighborhoodPca(const float* xyz, const NeighborLists& lists, int threads,
                            std::vector<PointPca>* out) {
  const std::size_t n = lists.points;
  out->resize(n);
  if (n == 0) return;
  constexpr std::size_t kBlock = 2048;
  const std::int64_t blocks = static_cast<std::int64_t>((n + kBlock - 1) / kBlock);
  const int all = threads > 0 ? threads : omp_get_num_procs();
  const int nt = static_cast<int>(std::min<std::size_t>(all, n / 1024 + 1));
#pragma omp parallel for num_threads(nt) schedule(static, 1)
  for (std::int64_t b = 0; b < blocks; ++b) {
    const std::size_t first = static_cast<std::size_t>(b) * kBlock;
    pcaRows(xyz, lists.indices.data(), lists.k, nullptr, first, std::min(kBlock, n - first),
            out->data());
  }
}

}  // namespace ground_filter
