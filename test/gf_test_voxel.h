// Test-only helpers shared by the voxel filter's tests (test_voxel_ground_filter.cpp,
// test_voxel_scale.cpp): the ground-level defaults, one filter run, label agreement.
#ifndef GROUND_FILTER_TEST_GF_TEST_VOXEL_H
#define GROUND_FILTER_TEST_GF_TEST_VOXEL_H

#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

#include "gf_test_scenes.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/voxel_ground_filter.h"

namespace gf_test {

namespace gf = ground_filter;

inline double agreement(const std::vector<std::uint8_t>& labels,
                        const std::vector<std::uint8_t>& truth, int only = -1) {
  std::size_t same = 0, total = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (only >= 0 && truth[i] != only) continue;
    ++total;
    same += labels[i] == truth[i];
  }
  return total ? static_cast<double>(same) / total : 1.0;
}

/// A 10 m x 10 m plane rising 10 % along x (1 cm noise) with a 1 m box standing on it.
inline TruthCloud slopeWithBox(unsigned seed) {
  std::mt19937 rng(seed);
  TruthCloud c;
  addSurface(
      &c, -5, 5, -5, 5, 0.05f, [](float x, float) { return 0.1f * x; }, 0.01f, &rng);
  addBox(&c, 1.f, 1.f, 1.f, 1.f, 0.1f, 1.f, 0.05f);
  return c;
}

// The defaults, ground-level steps: the synthetic clouds here are sampled evenly, as an airborne
// scan is, so scan_type auto would run them in the airborne mode (test_scan_type covers auto).
inline gf::VoxelGroundFilterParams groundLevel() {
  gf::VoxelGroundFilterParams p;
  p.scan_type = "ground";
  return p;
}

inline std::vector<std::uint8_t> run(const TruthCloud& c,
                                     const gf::VoxelGroundFilterParams& p = groundLevel(),
                                     gf::FilterStats* st = nullptr) {
  gf::VoxelGroundFilter f(p);
  std::vector<std::uint8_t> labels;
  f.filter(c.view(), &labels, st);
  return labels;
}

/// The defaults with the vegetation rule (veg_filter, its own defaults) on or off.
inline gf::VoxelGroundFilterParams vegetationRule(bool on) {
  gf::VoxelGroundFilterParams p = groundLevel();
  p.veg_filter = on;
  return p;
}

}  // namespace gf_test

#endif  // GROUND_FILTER_TEST_GF_TEST_VOXEL_H
