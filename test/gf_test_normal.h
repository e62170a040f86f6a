// Synthetic clouds of the normal-filter tests (test_normal_ground_filter, test_normal_knn_pca,
// test_normal_internals).
#ifndef GROUND_FILTER_TEST_GF_TEST_NORMAL_H
#define GROUND_FILTER_TEST_GF_TEST_NORMAL_H

#include <cmath>
#include <random>
#include <vector>

namespace gf_test_normal {

using Cloud = std::vector<float>;  // packed x y z

inline void add(Cloud* c, double x, double y, double z) {
  c->push_back(static_cast<float>(x));
  c->push_back(static_cast<float>(y));
  c->push_back(static_cast<float>(z));
}

/// Square grid of side `side` [m] at `step` spacing on z = z0 + slope_x * x, with Gaussian noise.
inline Cloud plane(double side, double step, double z0, double slope_x = 0.0, double noise = 0.0,
                   unsigned seed = 1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise > 0.0 ? noise : 1.0);
  Cloud c;
  const int cells = static_cast<int>(std::round(side / step));
  for (int i = 0; i < cells; ++i) {
    for (int j = 0; j < cells; ++j) {
      const double x = -side / 2 + (i + 0.5) * step, y = -side / 2 + (j + 0.5) * step;
      add(&c, x, y, z0 + slope_x * x + (noise > 0.0 ? n(rng) : 0.0));
    }
  }
  return c;
}

}  // namespace gf_test_normal

#endif  // GROUND_FILTER_TEST_GF_TEST_NORMAL_H
