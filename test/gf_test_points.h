// Test-only packed x y z clouds shared by the core's neighbour and PCA tests.
#ifndef GROUND_FILTER_TEST_GF_TEST_POINTS_H
#define GROUND_FILTER_TEST_GF_TEST_POINTS_H

#include <cstddef>
#include <random>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/io/scan_io.h"

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

}  // namespace gf_test

#endif  // GROUND_FILTER_TEST_GF_TEST_POINTS_H
