#ifndef GROUND_FILTER_SRC_CORE_KNN_PCA_CPU_GPU_COMMON_H
#define GROUND_FILTER_SRC_CORE_KNN_PCA_CPU_GPU_COMMON_H

// The PCA's sums and covariance of a neighbourhood, which the CPU (neighborhood_pca.cpp) and
// the CUDA kernels (cuda/src/knn_pca.cuh) must compute alike: one source, compiled by the host
// compiler and by nvcc (neither fuses a * b + c: -ffp-contract=off, -fmad=false).

#include <cstddef>
#include <cstdint>

#include "common/host_device.h"

namespace ground_filter {

/// \brief Sums of a neighbourhood's offsets (dx, dy, dz) from its query point and of their
///        products, in double, added in the neighbour list's order.
struct NeighborhoodSums {
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  int m = 0;  // offsets added
  GF_HOST_DEVICE void add(double dx, double dy, double dz) {
    ++m;
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
};

/// \brief The sums of list `row` (up to `k` indices into the packed `xyz`; the first -1 ends
///        it) around the query point (ox, oy, oz). The offsets are small (a neighbourhood, not
///        80 m ranges), so centring afterwards loses nothing measurable and each neighbour is
///        read once. (__restrict__: the kernels read both through the read-only cache.)
GF_HOST_DEVICE inline NeighborhoodSums neighborhoodSums(const float* __restrict__ xyz,
                                                        const std::int32_t* __restrict__ row, int k,
                                                        double ox, double oy, double oz) {
  NeighborhoodSums s;
  while (s.m < k && row[s.m] >= 0) {
    const float* p = xyz + 3 * static_cast<std::size_t>(row[s.m]);
    s.add(p[0] - ox, p[1] - oy, p[2] - oz);
  }
  return s;
}

/// \brief Centred covariance of a neighbourhood (upper triangle) and its trace.
struct NeighborhoodCovariance {
  double xx, xy, xz, yy, yz, zz, trace;
};

/// \brief The covariance from the sums; false when the PCA is invalid (fewer than 3 neighbours
///        or all of them (nearly) the same point).
GF_HOST_DEVICE inline bool covarianceOf(const NeighborhoodSums& s, NeighborhoodCovariance* c) {
  if (s.m < 3) return false;
  const double inv = 1.0 / s.m, mx = s.sx * inv, my = s.sy * inv, mz = s.sz * inv;
  const double cxx = s.sxx * inv - mx * mx, cxy = s.sxy * inv - mx * my,
               cxz = s.sxz * inv - mx * mz, cyy = s.syy * inv - my * my,
               cyz = s.syz * inv - my * mz, czz = s.szz * inv - mz * mz;
  const double trace = cxx + cyy + czz;
  if (!(trace > 1e-12)) return false;  // all neighbours (nearly) the same point
  *c = NeighborhoodCovariance{cxx, cxy, cxz, cyy, cyz, czz, trace};
  return true;
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_KNN_PCA_CPU_GPU_COMMON_H
