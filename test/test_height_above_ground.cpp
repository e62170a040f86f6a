// Height above ground (include/ground_filter/height_above_ground.h): exact heights on a tilted
// plane, a kerb, a roof in an occlusion shadow, single-point cells, negative heights, invalid
// points, no ground, points beyond the radius, the accuracy on a generated street scene with
// its truth labels, bad parameters, determinism, the same surface on every SIMD path and record
// layout, no allocation once the buffers are sized.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "eval/scene_generator.h"
#include "gf_test_alloc_counter.h"  // allocationCount()
#include "gf_test_scenes.h"
#include "ground_filter/height_above_ground.h"
#include "simd/simd.h"

namespace gf = ground_filter;
using gf_test::TruthCloud;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

float plane(float x, float y) { return 0.3f + 0.05f * x - 0.12f * y; }

// A regular grid of ground points on z = height(x, y), every `step` metres.
template <typename Fn>
TruthCloud groundGrid(float x0, float x1, float y0, float y1, float step, Fn height) {
  TruthCloud c;
  for (float x = x0; x < x1; x += step) {
    for (float y = y0; y < y1; y += step) c.add(x, y, height(x, y), true);
  }
  return c;
}

gf::GroundSurface built(const TruthCloud& c, const gf::GroundSurfaceParams& p = {}) {
  gf::GroundSurface s;
  s.build(c.view(), c.truth, p);
  return s;
}

float quantile(std::vector<float> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

TEST(HeightAboveGround, TiltedPlaneGivesExactHeights) {
  TruthCloud c = groundGrid(-10.f, 10.f, -10.f, 10.f, 0.25f, plane);
  const std::size_t ground = c.size();
  // Points above and between the ground samples, and off the cell centres.
  for (float x = -8.3f; x < 8.f; x += 1.37f) {
    for (float y = -7.9f; y < 8.f; y += 0.91f) c.add(x, y, plane(x, y) + 1.5f, false);
  }
  const gf::GroundSurface s = built(c);
  std::vector<float> h;
  s.heights(c.view(), &h);
  ASSERT_EQ(h.size(), c.size());
  for (std::size_t i = 0; i < c.size(); ++i) {
    const float expect = i < ground ? 0.f : 1.5f;
    EXPECT_NEAR(h[i], expect, 2e-3)
        << "point " << i << " at " << c.xyz[3 * i] << ", " << c.xyz[3 * i + 1];
  }
  // Between and beyond the samples, within the radius: the plane extended.
  EXPECT_NEAR(s.heightAbove(12.f, 3.f, plane(12.f, 3.f) + 0.7f), 0.7f, 0.02f);
  for (const gf::SurfaceCell& cell : s.cells()) {
    EXPECT_NEAR(cell.z, plane(cell.x, cell.y), 2e-3);
    // Exact plane, no residual: the confidence is n / (n + 3).
    EXPECT_NEAR(cell.confidence, cell.points / (cell.points + 3.0), 1e-4);
  }
}

TEST(HeightAboveGround, KerbStepIsKeptAwayFromTheEdge) {
  auto kerb = [](float, float y) { return y >= 0.f ? 0.15f : 0.f; };
  TruthCloud c = groundGrid(-10.f, 10.f, -10.f, 10.f, 0.2f, kerb);
  const gf::GroundSurface s = built(c);
  // One cell or more from the kerb line, the height is exact; at the line it lies between.
  EXPECT_NEAR(s.heightAbove(0.3f, -1.6f, 1.f), 1.f, 2e-3);
  EXPECT_NEAR(s.heightAbove(0.3f, 1.6f, 1.f), 0.85f, 2e-3);
  const float at = s.heightAbove(0.3f, 0.f, 1.f);
  EXPECT_GE(at, 0.85f - 1e-3f);
  EXPECT_LE(at, 1.f + 1e-3f);
  // Continuous across the line: small steps give small changes.
  float last = s.heightAbove(0.3f, -1.5f, 1.f);
  for (float y = -1.5f; y <= 1.5f; y += 0.01f) {
    const float now = s.heightAbove(0.3f, y, 1.f);
    EXPECT_LT(std::fabs(now - last), 0.01f) << "y " << y;
    last = now;
  }
}

TEST(HeightAboveGround, SpikeCellLabelledGroundIsDropped) {
  TruthCloud c;
  for (float x = -10.f; x < 10.f; x += 0.25f) {
    for (float y = -10.f; y < 10.f; y += 0.25f) {
      if (!(x >= 3.f && x < 4.f && y >= 3.f && y < 4.f)) c.add(x, y, 0.f, true);
    }
  }
  // In the one cell left out: "ground" 0.5 m up (a bush labelled ground).
  for (float x = 3.1f; x < 4.f; x += 0.2f) {
    for (float y = 3.1f; y < 4.f; y += 0.2f) c.add(x, y, 0.5f, true);
  }
  const gf::GroundSurface s = built(c);
  EXPECT_NEAR(s.heightAbove(3.5f, 3.5f, 0.5f), 0.5f, 1e-3);
  for (const gf::SurfaceCell& cell : s.cells()) {
    EXPECT_LT(cell.z, 0.3f) << "cell " << cell.x << ", " << cell.y;
  }
  EXPECT_EQ(s.cells().size(), 399u);  // the 20 x 20 cells of the flat ground less the spike
  EXPECT_NEAR(s.heightAbove(0.5f, 0.5f, 1.f), 1.f, 1e-3);
}

// Flat ground on 20 x 20 cells with a 3 x 3-cell patch (x, y in 2..5) at `patch` m labelled
// ground: a bush's base or undergrowth seen as ground, or a low platform.
gf::GroundSurface withPatch(float patch) {
  TruthCloud c;
  for (float x = -10.f; x < 10.f; x += 0.25f) {
    for (float y = -10.f; y < 10.f; y += 0.25f) {
      const bool in = x >= 2.f && x < 5.f && y >= 2.f && y < 5.f;
      c.add(x, y, in ? patch : 0.f, true);
    }
  }
  return built(c);
}

TEST(HeightAboveGround, PatchLabelledGroundIsDroppedAStepIsKept) {
  // 0.5 m: the middle cell's 8 neighbours are the patch (it passes the 8-neighbour test), but
  // two cells out the flat ground is the majority: the whole patch is dropped and filled.
  const gf::GroundSurface s = withPatch(0.5f);
  EXPECT_EQ(s.cells().size(), 400u - 9u);
  for (const gf::SurfaceCell& cell : s.cells()) {
    EXPECT_LT(cell.z, 0.01f) << "cell " << cell.x << ", " << cell.y;
  }
  EXPECT_NEAR(s.heightAbove(3.5f, 3.5f, 0.5f), 0.5f, 1e-3);
  // 0.30 m: a step (under 0.35 m above the wider window, the corners excepted: they stand
  // above 5 of their 8 neighbours by more than 0.25 m).
  const gf::GroundSurface step = withPatch(0.30f);
  EXPECT_EQ(step.cells().size(), 400u - 4u);
  EXPECT_NEAR(step.heightAbove(3.5f, 3.5f, 0.30f), 0.f, 1e-3);
  EXPECT_NEAR(step.elevation(3.5f, 2.5f), 0.30f, 1e-3);  // an edge cell of the step
  // 0.40 m: above the wider test's 0.35 m, the whole patch is dropped as at 0.5 m.
  EXPECT_EQ(withPatch(0.40f).cells().size(), 400u - 9u);
}

// Flat ground on 20 x 20 cells with a 2 x 2-cell roof (x, y in 2..4) at `roof` m labelled
// ground, the cells within 2 of it empty: a car beside a LiDAR, its roof seen as ground, with
// the blind zone and its occlusion shadow around it.
gf::GroundSurface roofInShadow(float roof, bool ground_level) {
  TruthCloud c;
  for (float x = -10.f; x < 10.f; x += 0.25f) {
    for (float y = -10.f; y < 10.f; y += 0.25f) {
      const bool on_roof = x >= 2.f && x < 4.f && y >= 2.f && y < 4.f;
      const bool shadow = x >= 0.f && x < 6.f && y >= 0.f && y < 6.f;
      if (on_roof || !shadow) c.add(x, y, on_roof ? roof : 0.f, true);
    }
  }
  gf::GroundSurfaceParams p;
  p.ground_level = ground_level;
  return built(c, p);
}

TEST(HeightAboveGround, RoofInAnOcclusionShadowIsDroppedInGroundLevelScansOnly) {
  // 1.4 m: the roof cells pass the 8-neighbour test (their neighbours are the roof) and the
  // 24-cell window is too empty to judge them; the ground 3-5 cells out is 1.4 m below.
  const gf::GroundSurface s = roofInShadow(1.4f, true);
  EXPECT_EQ(s.cells().size(), 400u - 36u);
  for (const gf::SurfaceCell& cell : s.cells()) {
    EXPECT_LT(cell.z, 0.01f) << "cell " << cell.x << ", " << cell.y;
  }
  EXPECT_NEAR(s.heightAbove(3.f, 3.f, 1.4f), 1.4f, 1e-3);  // filled from the ground around
  // An airborne scan's surface has no shadow test: the roof stays (its gaps are buildings and
  // steep slopes, where the test would drop true ground).
  const gf::GroundSurface air = roofInShadow(1.4f, false);
  EXPECT_EQ(air.cells().size(), 400u - 32u);
  EXPECT_NEAR(air.heightAbove(3.f, 3.f, 1.4f), 0.f, 1e-3);
  // 0.8 m: under the shadow test's 1.0 m (a loading platform, a raised bed): kept.
  const gf::GroundSurface low = roofInShadow(0.8f, true);
  EXPECT_EQ(low.cells().size(), 400u - 32u);
  EXPECT_NEAR(low.heightAbove(3.f, 3.f, 0.8f), 0.f, 1e-3);
}

TEST(HeightAboveGround, SingleGroundPointCellAndNegativeHeights) {
  TruthCloud c;
  c.xyz.reserve(16);             // (GCC 12 warns of a false overflow in a tiny insert otherwise)
  c.add(0.4f, 0.6f, 2.f, true);  // the only ground point: one cell, its z, no slope
  c.add(0.5f, 0.5f, 3.f, false);
  c.add(0.5f, 0.5f, 1.2f, false);  // below the ground (a reflection, a ditch)
  const gf::GroundSurface s = built(c);
  ASSERT_EQ(s.cells().size(), 1u);
  EXPECT_EQ(s.cells()[0].points, 1u);
  EXPECT_FLOAT_EQ(s.cells()[0].z, 2.f);
  EXPECT_FLOAT_EQ(s.cells()[0].confidence, 0.25f);
  std::vector<float> h;
  s.heights(c.view(), &h);
  EXPECT_NEAR(h[0], 0.f, 1e-5);
  EXPECT_NEAR(h[1], 1.f, 1e-5);
  EXPECT_NEAR(h[2], -0.8f, 1e-5);
}

TEST(HeightAboveGround, InvalidPointsGiveNaN) {
  TruthCloud c = groundGrid(-5.f, 5.f, -5.f, 5.f, 0.5f, plane);
  c.add(kNaN, 0.f, 1.f, true);  // labelled ground yet invalid: ignored
  c.add(0.f, kInf, 1.f, false);
  c.add(1.f, 1.f, -kInf, false);
  const gf::GroundSurface s = built(c);
  std::vector<float> h;
  s.heights(c.view(), &h);
  const std::size_t n = c.size();
  EXPECT_TRUE(std::isnan(h[n - 3]));
  EXPECT_TRUE(std::isnan(h[n - 2]));
  EXPECT_TRUE(std::isnan(h[n - 1]));
  EXPECT_NEAR(h[0], 0.f, 2e-3);
  EXPECT_TRUE(std::isnan(s.heightAbove(kNaN, 0.f, 0.f)));
  EXPECT_TRUE(std::isnan(s.heightAbove(0.f, 0.f, kInf)));
}

TEST(HeightAboveGround, NoGroundGivesAllNaN) {
  TruthCloud c = groundGrid(-5.f, 5.f, -5.f, 5.f, 0.5f, plane);
  std::fill(c.truth.begin(), c.truth.end(), 0);
  gf::GroundSurface s = built(c);
  std::vector<float> h;
  s.heights(c.view(), &h);
  ASSERT_EQ(h.size(), c.size());
  EXPECT_TRUE(std::all_of(h.begin(), h.end(), [](float v) { return std::isnan(v); }));
  EXPECT_TRUE(s.cells().empty());
  // An empty cloud too; and a surface rebuilt after a scan with ground forgets it.
  TruthCloud g = groundGrid(-5.f, 5.f, -5.f, 5.f, 0.5f, plane);
  s.build(g.view(), g.truth, gf::GroundSurfaceParams());
  EXPECT_FALSE(s.cells().empty());
  s.build(gf::CloudView(), {}, gf::GroundSurfaceParams());
  EXPECT_TRUE(s.cells().empty());
  EXPECT_TRUE(std::isnan(s.heightAbove(0.f, 0.f, 1.f)));
}

TEST(HeightAboveGround, BeyondTheRadiusIsNaN) {
  TruthCloud c = groundGrid(-2.f, 2.f, -2.f, 2.f, 0.25f, [](float, float) { return 0.f; });
  c.add(9.5f, 0.f, 1.f, false);   // 7.5 m from the nearest ground: beyond radius 5
  c.add(-5.5f, 0.f, 1.f, false);  // 3.5 m from the nearest ground: filled
  gf::GroundSurfaceParams p;
  p.radius = 5.0;
  const gf::GroundSurface s = built(c, p);
  std::vector<float> h;
  s.heights(c.view(), &h);
  const std::size_t n = c.size();
  EXPECT_TRUE(std::isnan(h[n - 2]));
  EXPECT_NEAR(h[n - 1], 1.f, 1e-3);
  // The same answers for points the build cloud did not hold.
  EXPECT_TRUE(std::isnan(s.heightAbove(0.f, 30.f, 1.f)));
  EXPECT_NEAR(s.heightAbove(0.f, -5.2f, 0.4f), 0.4f, 1e-3);
  // radius 0: no fill at all.
  p.radius = 0.0;
  const gf::GroundSurface none = built(c, p);
  EXPECT_TRUE(std::isnan(none.heightAbove(-5.5f, 0.f, 1.f)));
  EXPECT_NEAR(none.heightAbove(0.f, 0.f, 1.f), 1.f, 1e-3);
}

// heights() runs eight points at a time where the CPU allows (GF_SIMD); heightAbove() one at a
// time: the same value bit for bit for every kind of point, on a cloud with a 16-byte record.
TEST(HeightAboveGround, HeightsEqualHeightAboveForEveryPoint) {
  std::vector<float> rec;  // x y z intensity
  std::vector<std::uint8_t> labels;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-9.f, 9.f), dz(-0.3f, 2.f);
  const auto ground = [](float x, float y) { return 0.2f + 0.1f * x - 0.05f * y * y / 9.f; };
  for (int k = 0; k < 4000; ++k) {
    const float x = u(rng), y = u(rng);
    const bool hole = x > 1.f && x < 4.f && y > -2.f && y < 3.f;  // no ground: filled, partial
    const bool g = !hole && k % 3 != 0;
    rec.insert(rec.end(), {x, y, g ? ground(x, y) : ground(x, y) + dz(rng), 0.f});
    labels.push_back(g ? 1 : 0);
  }
  // Beyond the radius, at the edge of the grid, and where only some of the four centres have an
  // elevation (x 10.9, 11.2: a blend renormalised).
  for (const float far : {-30.f, 10.9f, 11.2f, 14.f, 16.5f, 40.f}) {
    rec.insert(rec.end(), {far, 0.5f, 1.f, 0.f, 0.5f, far, 1.f, 0.f});
    labels.insert(labels.end(), {0, 0});
  }
  rec.insert(rec.end(), {kNaN, 0.f, 0.f, 0.f, 0.f, kInf, 0.f, 0.f, 1.f, 1.f, kNaN, 0.f});
  labels.insert(labels.end(), {0, 1, 0});
  const std::size_t n = labels.size();  // 4015: not a multiple of 8 (a scalar tail)
  const gf::CloudView view(rec.data(), n, 4 * sizeof(float), 0, sizeof(float), 2 * sizeof(float));
  gf::GroundSurfaceParams p;
  p.radius = 2.5;  // the hole's middle lies beyond it: NaN centres next to defined ones
  gf::GroundSurface s;
  s.build(view, labels, p);
  std::vector<float> h;
  s.heights(view, &h);
  ASSERT_EQ(h.size(), n);
  std::size_t nan = 0, same = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float* r = &rec[4 * i];
    const float one = s.heightAbove(r[0], r[1], r[2]);
    nan += std::isnan(h[i]) ? 1 : 0;
    same += (std::isnan(one) && std::isnan(h[i])) || one == h[i] ? 1 : 0;
  }
  EXPECT_EQ(same, n);
  EXPECT_GE(nan, 8u + 3u);  // the points at -30, 14, 16.5, 40 and the invalid ones at least
  EXPECT_LT(nan, n / 10);
}

TEST(HeightAboveGround, GeneratedStreetWithTruthLabels) {
  const gf::SceneParams params = gf::builtinSceneParams("lidar");
  const gf::GeneratedScan scan = gf::generateScene(params);
  const gf::CloudView view = gf::CloudView::packedXyz(scan.xyz.data(), scan.size());
  gf::GroundSurface s;
  s.build(view, scan.truth, gf::GroundSurfaceParams());
  std::vector<float> h;
  s.heights(view, &h);
  std::vector<float> err;
  std::size_t nan = 0, finite = 0;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    float x, y, z;
    if (!view.get(i, &x, &y, &z)) continue;
    ++finite;
    if (std::isnan(h[i])) {
      ++nan;
      continue;
    }
    const double truth = z - gf::sceneGroundHeight(params, x, y);
    err.push_back(static_cast<float>(std::fabs(h[i] - truth)));
  }
  ASSERT_GT(err.size(), finite / 2);
  // Goal of docs/height_above_ground.md: median <= 0.05 m, p95 <= 0.15 m.
  EXPECT_LE(quantile(err, 0.5), 0.05f);
  EXPECT_LE(quantile(err, 0.95), 0.15f);
  EXPECT_LT(static_cast<double>(nan) / static_cast<double>(finite), 0.05);
}

TEST(HeightAboveGround, BadParamsAreRefusedByName) {
  const TruthCloud c = groundGrid(-2.f, 2.f, -2.f, 2.f, 0.5f, plane);
  gf::GroundSurface s;
  auto refused = [&](const gf::GroundSurfaceParams& p, const std::string& name) {
    try {
      s.build(c.view(), c.truth, p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what()).find("'" + name + "'") != std::string::npos;
    }
    return false;
  };
  gf::GroundSurfaceParams p;
  p.cell = 0.0;
  EXPECT_TRUE(refused(p, "cell"));
  p.cell = std::nan("");
  EXPECT_TRUE(refused(p, "cell"));
  p = gf::GroundSurfaceParams();
  p.radius = -1.0;
  EXPECT_TRUE(refused(p, "radius"));
  p.radius = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(refused(p, "radius"));
  p = gf::GroundSurfaceParams();
  p.threads = -1;
  EXPECT_TRUE(refused(p, "threads"));
  p.threads = 257;
  EXPECT_TRUE(refused(p, "threads"));
  EXPECT_THROW(s.build(c.view(), std::vector<std::uint8_t>(3, 1), gf::GroundSurfaceParams()),
               std::invalid_argument);
  EXPECT_NO_THROW(gf::GroundSurfaceParams().validate());
}

TEST(HeightAboveGround, TwoBuildsGiveIdenticalHeights) {
  const gf::SceneParams params = gf::builtinSceneParams("verge");
  const gf::GeneratedScan scan = gf::generateScene(params);
  const gf::CloudView view = gf::CloudView::packedXyz(scan.xyz.data(), scan.size());
  gf::GroundSurface a, b;
  a.build(view, scan.truth, gf::GroundSurfaceParams());
  // b first sees another scan, so it reuses its buffers.
  const TruthCloud other = groundGrid(-30.f, 30.f, -3.f, 3.f, 0.5f, plane);
  b.build(other.view(), other.truth, gf::GroundSurfaceParams());
  b.build(view, scan.truth, gf::GroundSurfaceParams());
  std::vector<float> ha, hb;
  a.heights(view, &ha);
  b.heights(view, &hb);
  ASSERT_EQ(ha.size(), hb.size());
  std::size_t same = 0;
  for (std::size_t i = 0; i < ha.size(); ++i) {
    same += (std::isnan(ha[i]) && std::isnan(hb[i])) || ha[i] == hb[i];
  }
  EXPECT_EQ(same, ha.size());
  ASSERT_EQ(a.cells().size(), b.cells().size());
  for (std::size_t k = 0; k < a.cells().size(); ++k) {
    EXPECT_EQ(a.cells()[k].z, b.cells()[k].z);
    EXPECT_EQ(a.cells()[k].points, b.cells()[k].points);
  }
  // Row by row, y then x ascending.
  for (std::size_t k = 1; k < a.cells().size(); ++k) {
    const gf::SurfaceCell &p = a.cells()[k - 1], &q = a.cells()[k];
    EXPECT_TRUE(p.y < q.y || (p.y == q.y && p.x < q.x)) << k;
  }
}

// build() collects the ground points and sums each cell eight points / four sums at a time where
// the CPU allows (AVX2: records whose x y z lie in 16 bytes), heights() looks the cells up in
// pairs: every code path and record layout gives the same cells and heights, bit for bit, as the
// portable code on bare x y z records (a generated street, with invalid points, an odd count).
TEST(HeightAboveGround, EveryCodePathAndLayoutGivesTheSameSurface) {
  using Level = gf::simd::Level;
  const gf::GeneratedScan scan = gf::generateScene(gf::builtinSceneParams("verge"));
  std::vector<float> xyz(scan.xyz.begin(), scan.xyz.end());
  std::vector<std::uint8_t> labels(scan.truth.begin(), scan.truth.end());
  for (std::size_t i = 0; i < labels.size(); i += 97) labels[i] = 1;  // ground among the rest
  for (std::size_t i = 5; i < labels.size(); i += 1009) xyz[3 * i + (i % 3)] = i % 2 ? kNaN : kInf;
  xyz.insert(xyz.end(), {1.f, 2.f, -0.1f, 3.f, 1.f, 0.f, kNaN, 0.f, 0.f});
  labels.insert(labels.end(), {1, 1, 1});
  const std::size_t n = labels.size();
  ASSERT_NE(n % 8, 0u);
  std::vector<float> rec;  // x y z intensity: the layout the AVX2 collection reads
  for (std::size_t i = 0; i < n; ++i)
    rec.insert(rec.end(), {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2], 7.f});
  const gf::CloudView bare = gf::CloudView::packedXyz(xyz.data(), n);
  const gf::CloudView wide(rec.data(), n, 4 * sizeof(float), 0, sizeof(float), 2 * sizeof(float));
  const auto run = [&](Level level, const gf::CloudView& view, std::vector<float>* h) {
    const gf::simd::ScopedLevel scoped(level);
    EXPECT_TRUE(scoped.ok());
    gf::GroundSurface s;
    s.build(view, labels, gf::GroundSurfaceParams());
    s.heights(view, h);
    return s.cells();
  };
  std::vector<float> want;
  const std::vector<gf::SurfaceCell> cells = run(Level::kPortable, bare, &want);
  ASSERT_GT(cells.size(), 100u);
  const auto bits = [](float v) {
    std::uint32_t u;
    std::memcpy(&u, &v, sizeof u);
    return std::isnan(v) ? 0x7fc00000u : u;
  };
  for (Level level : {Level::kPortable, Level::kSse, Level::kAvx2, Level::kAvx512, Level::kNeon}) {
    if (!gf::simd::supported(level)) continue;
    for (const gf::CloudView* view : {&bare, &wide}) {
      SCOPED_TRACE(std::string(gf::simd::levelName(level)) +
                   (view == &wide ? ", 16-byte records" : ", x y z"));
      std::vector<float> h;
      const std::vector<gf::SurfaceCell> got = run(level, *view, &h);
      ASSERT_EQ(got.size(), cells.size());
      std::size_t same = 0;
      for (std::size_t k = 0; k < cells.size(); ++k) {
        const gf::SurfaceCell &a = cells[k], &b = got[k];
        same += a.x == b.x && a.y == b.y && bits(a.z) == bits(b.z) && a.points == b.points &&
                bits(a.confidence) == bits(b.confidence);
      }
      EXPECT_EQ(same, cells.size());
      ASSERT_EQ(h.size(), n);
      same = 0;
      for (std::size_t i = 0; i < n; ++i) same += bits(h[i]) == bits(want[i]);
      EXPECT_EQ(same, n);
    }
  }
}

// heights() splits the points over params.threads: every point written once, with the same
// value; the cells do not depend on it either.
TEST(HeightAboveGround, SurfaceAndHeightsAreTheSameForAnyThreadCount) {
  const gf::GeneratedScan scan = gf::generateScene(gf::builtinSceneParams("lidar"));
  std::vector<float> xyz(scan.xyz.begin(), scan.xyz.end());
  xyz.insert(xyz.end(), {1.f, 2.f, -0.1f, kNaN, 0.f, 0.f, 3.f, 1.f, 0.f});  // not a multiple of 8
  std::vector<std::uint8_t> labels(scan.truth.begin(), scan.truth.end());
  labels.insert(labels.end(), {1, 1, 0});
  const std::size_t n = labels.size();
  ASSERT_GT(n, 100000u);  // several threads' worth (16 k points each at least)
  ASSERT_NE(n % 8, 0u);
  const gf::CloudView view = gf::CloudView::packedXyz(xyz.data(), n);
  std::vector<gf::SurfaceCell> cells;
  const auto heights = [&](int threads) {
    gf::GroundSurfaceParams p;
    p.threads = threads;
    gf::GroundSurface s;
    s.build(view, labels, p);
    std::vector<float> h(n, 12345.f);  // a point left out keeps this
    s.heights(view, &h);
    cells = s.cells();
    return h;
  };
  const std::vector<float> want = heights(1);
  const std::vector<gf::SurfaceCell> want_cells = cells;
  std::size_t finite = 0;
  for (float v : want) finite += std::isfinite(v) && v != 12345.f;
  EXPECT_GT(finite, n * 9 / 10);
  // The largest team first: LLVM's libomp (the sanitizer build's) keeps the thread table it
  // outgrows, which LeakSanitizer reports at exit.
  for (int threads : {7, 3, 2, 0}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    const std::vector<float> got = heights(threads);
    ASSERT_EQ(cells.size(), want_cells.size());
    std::size_t same = 0;
    for (std::size_t k = 0; k < cells.size(); ++k) {
      const gf::SurfaceCell &a = cells[k], &b = want_cells[k];
      same += a.x == b.x && a.y == b.y && a.z == b.z && a.points == b.points &&
              a.confidence == b.confidence;
    }
    EXPECT_EQ(same, cells.size());
    ASSERT_EQ(got.size(), n);
    same = 0;
    for (std::size_t i = 0; i < n; ++i) {
      same += std::memcmp(&got[i], &want[i], sizeof(float)) == 0 ||
              (std::isnan(got[i]) && std::isnan(want[i]));
    }
    EXPECT_EQ(same, n);
  }
}

TEST(HeightAboveGround, NoAllocationAfterTheFirstScan) {
  const gf::SceneParams params = gf::builtinSceneParams("lidar");
  const gf::GeneratedScan scan = gf::generateScene(params);
  const gf::CloudView view = gf::CloudView::packedXyz(scan.xyz.data(), scan.size());
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    gf::GroundSurfaceParams p;
    p.threads = threads;
    gf::GroundSurface s;
    std::vector<float> h;
    s.build(view, scan.truth, p);
    s.heights(view, &h);
    const std::size_t before = allocationCount().load();
    s.build(view, scan.truth, p);
    s.heights(view, &h);
    EXPECT_EQ(allocationCount().load() - before, 0u);
    EXPECT_FALSE(s.cells().empty());
  }
}

}  // namespace
