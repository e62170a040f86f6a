// Private: per-point PCA of the KNN lists on the device. Mirrors the core's
// computeNeighborhoodPca(): one pass of sums of the neighbours' offsets from the query point and
// their products in double, the covariance from them, then Eigen's closed-form 3x3 solver
// (SelfAdjointEigenSolver::computeDirect) step by step, so both give the same normal and
// eigenvalues (the library is built without FMA contraction; sqrt is exact, atan2/cos/sin may
// differ in the last bit).
#ifndef GROUND_FILTER_CUDA_SRC_KNN_PCA_CUH
#define GROUND_FILTER_CUDA_SRC_KNN_PCA_CUH

#include <cuda_runtime.h>

#include <cmath>
#include <cstdint>

#include "knn/pca_cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

constexpr double kDblEps = 2.220446049250313e-16;  // NumTraits<double>::epsilon()

__device__ inline void cross3(const double a[3], const double b[3], double c[3]) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

__device__ inline double sqNorm3(const double a[3]) {
  return a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
}

/// Eigen's extract_kernel: unit vector spanning the kernel of the rank-2 matrix `m`.
__device__ inline void extractKernel(const double m[3][3], double res[3], double rep[3]) {
  int i0 = 0;
  double best = fabs(m[0][0]);
  if (fabs(m[1][1]) > best) {
    i0 = 1;
    best = fabs(m[1][1]);
  }
  if (fabs(m[2][2]) > best) i0 = 2;
  const int i1 = (i0 + 1) % 3, i2 = (i0 + 2) % 3;
  for (int r = 0; r < 3; ++r) rep[r] = m[r][i0];
  const double a[3] = {m[0][i1], m[1][i1], m[2][i1]}, b[3] = {m[0][i2], m[1][i2], m[2][i2]};
  double c0[3], c1[3];
  cross3(rep, a, c0);
  cross3(rep, b, c1);
  const double n0 = sqNorm3(c0), n1 = sqNorm3(c1);
  if (n0 > n1) {
    const double s = sqrt(n0);
    for (int r = 0; r < 3; ++r) res[r] = c0[r] / s;
  } else {
    const double s = sqrt(n1);
    for (int r = 0; r < 3; ++r) res[r] = c1[r] / s;
  }
}

/// Eigen's computeDirect for a symmetric 3x3 matrix: ascending eigenvalues and the eigenvector of
/// the smallest one (column 0).
__device__ inline void eigenDirect3(const double a[3][3], double ev[3], double v0[3]) {
  const double shift = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
  double s[3][3];
  double scale = 0.0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      s[r][c] = a[r][c] - (r == c ? shift : 0.0);
      scale = fmax(scale, fabs(s[r][c]));
    }
  }
  if (scale > 0.0) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) s[r][c] /= scale;
    }
  }
  // computeRoots
  {
    const double inv3 = 1.0 / 3.0, sqrt3 = sqrt(3.0);
    const double c0 = s[0][0] * s[1][1] * s[2][2] + 2.0 * s[1][0] * s[2][0] * s[2][1] -
                      s[0][0] * s[2][1] * s[2][1] - s[1][1] * s[2][0] * s[2][0] -
                      s[2][2] * s[1][0] * s[1][0];
    const double c1 = s[0][0] * s[1][1] - s[1][0] * s[1][0] + s[0][0] * s[2][2] -
                      s[2][0] * s[2][0] + s[1][1] * s[2][2] - s[2][1] * s[2][1];
    const double c2 = s[0][0] + s[1][1] + s[2][2];
    const double c2_over_3 = c2 * inv3;
    double a_over_3 = (c2 * c2_over_3 - c1) * inv3;
    a_over_3 = a_over_3 > 0.0 ? a_over_3 : 0.0;
    const double half_b = 0.5 * (c0 + c2_over_3 * (2.0 * c2_over_3 * c2_over_3 - c1));
    double qq = a_over_3 * a_over_3 * a_over_3 - half_b * half_b;
    qq = qq > 0.0 ? qq : 0.0;
    const double rho = sqrt(a_over_3);
    const double theta = atan2(sqrt(qq), half_b) * inv3;
    const double cos_t = cos(theta), sin_t = sin(theta);
    ev[0] = c2_over_3 - rho * (cos_t + sqrt3 * sin_t);
    ev[1] = c2_over_3 - rho * (cos_t - sqrt3 * sin_t);
    ev[2] = c2_over_3 + 2.0 * rho * cos_t;
  }
  if (ev[2] - ev[0] <= kDblEps) {
    v0[0] = 1.0;
    v0[1] = v0[2] = 0.0;
  } else {
    double d0 = ev[2] - ev[1];
    const double d1 = ev[1] - ev[0];
    int k = 0, l = 2;
    if (d0 > d1) {
      k = 2;
      l = 0;
      d0 = d1;
    }
    double tmp[3][3];
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) tmp[r][c] = s[r][c] - (r == c ? ev[k] : 0.0);
    }
    double vk[3], vl[3];
    extractKernel(tmp, vk, vl);
    if (k == 0) {
      for (int r = 0; r < 3; ++r) v0[r] = vk[r];
    } else {
      if (d0 <= 2.0 * kDblEps * d1) {
        const double dot = vk[0] * vl[0] + vk[1] * vl[1] + vk[2] * vl[2];
        for (int r = 0; r < 3; ++r) vl[r] -= dot * vl[r];  // sic (Eigen 3.4)
        const double z = sqNorm3(vl);
        if (z > 0.0) {
          const double sz = sqrt(z);
          for (int r = 0; r < 3; ++r) vl[r] /= sz;
        }
      } else {
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) tmp[r][c] = s[r][c] - (r == c ? ev[l] : 0.0);
        }
        double dummy[3];
        extractKernel(tmp, vl, dummy);
      }
      for (int r = 0; r < 3; ++r) v0[r] = vl[r];
    }
  }
  for (int r = 0; r < 3; ++r) {
    ev[r] *= scale;
    ev[r] += shift;
  }
}

/// PCA of one neighbourhood: `row` holds up to k original indices into packed `xyz` (-1 ends
/// it), (ox, oy, oz) is the query point. Returns false (outputs zero) when fewer than 3
/// neighbours or no spread; else the unit normal (smallest eigenvalue's eigenvector) and the
/// eigenvalues ascending, divided by their sum.
__device__ inline bool neighborhoodPcaOf(const float* __restrict__ xyz,
                                         const std::int32_t* __restrict__ row, int k, float qx,
                                         float qy, float qz, float normal[3], float eigen[3]) {
  for (int r = 0; r < 3; ++r) normal[r] = eigen[r] = 0.f;
  // The CPU's sums and covariance (one source: knn/pca_cpu_gpu_common.h).
  NeighborhoodCovariance c;
  if (!covarianceOf(neighborhoodSums(xyz, row, k, qx, qy, qz), &c)) return false;
  const double cov[3][3] = {{c.xx, c.xy, c.xz}, {c.xy, c.yy, c.yz}, {c.xz, c.yz, c.zz}};
  double ev[3], nv[3];
  eigenDirect3(cov, ev, nv);
  for (int r = 0; r < 3; ++r) ev[r] = ev[r] < 0.0 ? 0.0 : ev[r];  // cwiseMax(0)
  const double sum = ev[0] + ev[1] + ev[2];
  if (!(sum > 0.0)) return false;
  if (!(isfinite(nv[0]) && isfinite(nv[1]) && isfinite(nv[2]))) return false;
  for (int r = 0; r < 3; ++r) {
    normal[r] = static_cast<float>(nv[r]);
    eigen[r] = static_cast<float>(ev[r] / sum);
  }
  return true;
}

/// PCA of every row of the KNN lists (rows in sorted order, `pts[s].w` = original index),
/// written at the original index: normals (3n), eigenvalues (3n), valid (n).
void launchPca(const float* xyz, const float4* pts, const std::int32_t* rows, int n, int k,
               float* normals, float* eigen, std::uint8_t* valid, cudaStream_t st);
/// For every row: neighbours whose flag is set and valid neighbours, at the original index.
void launchCountFlagged(const float4* pts, const std::int32_t* rows, int n, int k,
                        const std::uint8_t* flags, std::uint16_t* flagged, std::uint16_t* neighbors,
                        cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_KNN_PCA_CUH
