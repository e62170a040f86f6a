// The airborne mode's morphological ground surface (src/core/airborne/morph_ground), called
// directly: rules of its own that the filters' tests do not isolate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "airborne/morph_ground.h"
#include "ground_filter/cloud_view.h"

namespace gf = ground_filter;

namespace {

/// The airborne mode's labels of packed x y z points with the default settings (every point
/// labelled).
std::vector<std::uint8_t> morphLabels(const std::vector<float>& xyz) {
  gf::MorphGround morph;
  std::vector<std::uint8_t> labels;
  const std::size_t n = xyz.size() / 3;
  EXPECT_EQ(morph.run(gf::CloudView::packedXyz(xyz.data(), n), gf::MorphGroundSettings(), &labels),
            n);
  return labels;
}

// Multipath and other low-noise returns lie metres below the terrain with nothing near them. As a
// cell's lowest return such a point would pit the surface (an opening removes bumps, not pits),
// and the bilinear surface would drag the ground around it below the height test. Terrain: a 4 %
// slope sampled every 0.5 m with 3 cm noise (4 returns per m², as a dense ALS tile); five single
// returns 2.5-8 m below it. All of them must come out non-ground and the ground within 2 m of
// them ground (without the rule 25 of the 251 ground returns within 2 m of them fail).
TEST(MorphGround, LowOutliersDoNotPitTheSurface) {
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.f, 0.03f);
  auto height = [](float x, float y) { return 100.f + 0.04f * x - 0.02f * y; };
  std::vector<float> xyz;
  std::vector<std::uint8_t> truth;
  for (float x = -30.f; x < 30.f; x += 0.5f) {
    for (float y = -30.f; y < 30.f; y += 0.5f) {
      xyz.insert(xyz.end(), {x, y, height(x, y) + noise(rng)});
      truth.push_back(1);
    }
  }
  const float outliers[5][3] = {{0.3f, 0.2f, 8.f},
                                {-15.2f, 10.1f, 5.f},
                                {12.7f, -14.6f, 3.f},
                                {20.4f, 20.3f, 2.5f},
                                {-20.1f, -20.4f, 6.f}};
  for (const auto& o : outliers) {
    xyz.insert(xyz.end(), {o[0], o[1], height(o[0], o[1]) - o[2]});
    truth.push_back(0);
  }
  const std::size_t n = truth.size();
  const std::vector<std::uint8_t> labels = morphLabels(xyz);
  ASSERT_EQ(labels.size(), n);
  std::size_t near = 0, near_kept = 0, ground = 0, ground_kept = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!truth[i]) {
      EXPECT_EQ(labels[i], 0) << "outlier at " << xyz[3 * i] << ", " << xyz[3 * i + 1];
      continue;
    }
    ++ground;
    ground_kept += labels[i];
    for (const auto& o : outliers) {
      if (std::hypot(xyz[3 * i] - o[0], xyz[3 * i + 1] - o[1]) < 2.f) {
        ++near;
        near_kept += labels[i];
      }
    }
  }
  ASSERT_GT(near, 200u);
  EXPECT_EQ(near_kept, near);
  EXPECT_EQ(ground_kept, ground);
}

// A narrow pit that is terrain keeps its floor: the rule asks for no return near the lowest one,
// not for the lowest to lie far below the mean or median of its surroundings (here 2-3 m).
TEST(MorphGround, APitWithWallsIsNotAnOutlier) {
  std::vector<float> xyz;
  std::vector<std::uint8_t> truth;
  for (float x = -20.f; x < 20.f; x += 0.5f) {
    for (float y = -20.f; y < 20.f; y += 0.5f) {
      // 3 m deep, 3 m wide at the bottom, walls 45 degrees: the floor's neighbours rise gradually.
      const float r = std::max(std::fabs(x), std::fabs(y));
      const float z = r < 1.5f ? -3.f : std::min(0.f, -3.f + (r - 1.5f));
      xyz.insert(xyz.end(), {x, y, z});
      truth.push_back(1);
    }
  }
  const std::vector<std::uint8_t> labels = morphLabels(xyz);
  ASSERT_EQ(labels.size(), truth.size());
  std::size_t floor = 0, floor_kept = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (xyz[3 * i + 2] < -2.9f) {
      ++floor;
      floor_kept += labels[i];
    }
  }
  ASSERT_GT(floor, 30u);
  EXPECT_EQ(floor_kept, floor);
}

// Under a dense canopy few pulses reach the ground: its returns can lie metres apart with only
// canopy above them (here one every 5 m on a 1 % slope, canopy 12-25 m up at 4 returns per m²,
// nothing in between). Each such return has canopy, and no return near its height, within 3 m,
// as a low outlier has; it is not one: the ground continues within a few metres. Every ground
// return must stay ground and the canopy non-ground (with the 3 m test alone all 144 ground
// returns left the surface and 1,165 canopy returns came out ground).
TEST(MorphGround, SparseGroundUnderACanopyIsNotAnOutlier) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> crown(12.f, 25.f), jitter(-0.2f, 0.2f);
  auto height = [](float x, float y) { return 50.f + 0.01f * x + 0.005f * y; };
  std::vector<float> xyz;
  std::vector<std::uint8_t> truth;
  for (float x = -30.f; x < 30.f; x += 5.f) {
    for (float y = -30.f; y < 30.f; y += 5.f) {
      const float gx = x + jitter(rng), gy = y + jitter(rng);
      xyz.insert(xyz.end(), {gx, gy, height(gx, gy)});
      truth.push_back(1);
    }
  }
  for (float x = -32.f; x < 32.f; x += 0.5f) {
    for (float y = -32.f; y < 32.f; y += 0.5f) {
      xyz.insert(xyz.end(), {x, y, height(x, y) + crown(rng)});
      truth.push_back(0);
    }
  }
  const std::size_t n = truth.size();
  const std::vector<std::uint8_t> labels = morphLabels(xyz);
  ASSERT_EQ(labels.size(), n);
  std::size_t ground = 0, ground_kept = 0, canopy_ground = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (truth[i]) {
      ++ground;
      ground_kept += labels[i];
    } else {
      canopy_ground += labels[i];
    }
  }
  ASSERT_EQ(ground, 144u);
  EXPECT_EQ(ground_kept, ground);
  EXPECT_EQ(canopy_ground, 0u);
}

}  // namespace
