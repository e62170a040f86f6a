// Test-only packed x y z clouds shared by the core's neighbour and PCA tests.
#ifndef GROUND_FILTER_TEST_GF_TEST_POINTS_H
#define GROUND_FILTER_TEST_GF_TEST_POINTS_H

#include <cmath>
#include <cstddef>
#include <random>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#ifdef GF_TEST_NO_SCAN_IO
#include "eval/kitti_bin.h"
#else
#include "eval/scan_io.h"
#endif

namespace gf_test {

/// \brief `n` packed x y z points, uniform in a flat box (x, y in [-10, 10] m, z in [-2, 2] m);
///        when `clustered`, every third point lies within `spread` m (per axis) of an earlier
///        one and every ninth exactly on it (dense spots and exact duplicates).
inline std::vector<float> randomCloud(std::size_t n, unsigned seed, bool clustered, float spread) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-10.f, 10.f), small(-spread, spread);
  std::vector<float> c;
  for (std::size_t i = 0; i < n; ++i) {
    if (clustered && i % 3 == 0 && i > 0) {
      const std::size_t j = rng() % i;
      const bool dup = i % 9 == 0;
      // Braced lists are evaluated left to right: the same cloud with any compiler.
      c.insert(c.end(),
               {c[3 * j] + (dup ? 0.f : small(rng)), c[3 * j + 1] + (dup ? 0.f : small(rng)),
                c[3 * j + 2] + (dup ? 0.f : small(rng))});
    } else {
      c.insert(c.end(), {u(rng), u(rng), 0.2f * u(rng)});
    }
  }
  return c;
}

#ifdef GF_TEST_NO_SCAN_IO
/// \brief Builds without PCL (test/core_only): the finite points of a KITTI .bin scan (float32
///        x y z intensity records), x y z packed; no points for any other file.
inline std::vector<float> finiteXyzOf(const std::string& file) {
  std::vector<float> c;
  if (file.size() < 4 || file.compare(file.size() - 4, 4, ".bin") != 0) return c;
  const std::vector<float> r = ground_filter::readKittiRecords(file);
  for (std::size_t i = 0; i + 3 < r.size(); i += 4) {
    if (std::isfinite(r[i]) && std::isfinite(r[i + 1]) && std::isfinite(r[i + 2])) {
      c.insert(c.end(), {r[i], r[i + 1], r[i + 2]});
    }
  }
  return c;
}
#else
/// \brief The finite points of a scan file (ground_filter::loadScan()), x y z packed.
inline std::vector<float> finiteXyzOf(const std::string& file) {
  const ground_filter::Scan scan = ground_filter::loadScan(file);
  const ground_filter::CloudView view = ground_filter::viewOf(scan.cloud);
  std::vector<float> c;
  for (std::size_t i = 0; i < view.size(); ++i) {
    float x, y, z;
    if (view.get(i, &x, &y, &z)) c.insert(c.end(), {x, y, z});
  }
  return c;
}
#endif  // GF_TEST_NO_SCAN_IO

}  // namespace gf_test

#endif  // GROUND_FILTER_TEST_GF_TEST_POINTS_H
