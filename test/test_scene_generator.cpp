// Tests of the procedural scene generator (the demo's default input and a test fixture).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <map>
#include <stdexcept>
#include <string>

#include "eval/scene_generator.h"

namespace ground_filter {
namespace {

struct Counts {
  std::size_t ground = 0;
  std::size_t nonground = 0;
  std::size_t nonfinite = 0;
  std::size_t nonground_above_1m = 0;  // non-ground points > 1 m above the terrain
  std::size_t canopy_over_road = 0;    // non-ground > 1.8 m up, above the road surface
  std::size_t ground_off_surface = 0;  // ground points farther than the tolerance from it
};

Counts count(const SceneParams& p, const GeneratedScan& s, double tolerance) {
  Counts c;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const float x = s.xyz[3 * i], y = s.xyz[3 * i + 1], z = s.xyz[3 * i + 2];
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
      ++c.nonfinite;
      continue;
    }
    const double dz = z - sceneGroundHeight(p, x, y);
    if (s.truth[i] == 1) {
      ++c.ground;
      if (std::fabs(dz) > tolerance) ++c.ground_off_surface;
    } else {
      ++c.nonground;
      if (dz > 1.0) ++c.nonground_above_1m;
      // Road between the far lane and the curb (scanner at world y = 0).
      if (dz > 1.8 && y > 4.0 && y < p.curb_y - 0.2) ++c.canopy_over_road;
    }
  }
  return c;
}

void expectConsistentSizes(const GeneratedScan& s) {
  EXPECT_EQ(s.xyz.size(), 3 * s.size());
  EXPECT_EQ(s.intensity.size(), s.size());
  EXPECT_EQ(s.ring.size(), s.size());
  EXPECT_EQ(s.truth.size(), s.size());
}

TEST(SceneGenerator, LidarIsDeterministicForASeed) {
  SceneParams p;
  p.seed = 7;
  const GeneratedScan a = generateScene(p);
  const GeneratedScan b = generateScene(p);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.xyz, b.xyz);
  EXPECT_EQ(a.intensity, b.intensity);
  EXPECT_EQ(a.ring, b.ring);
  EXPECT_EQ(a.truth, b.truth);

  p.seed = 8;  // another layout
  const GeneratedScan c = generateScene(p);
  EXPECT_NE(a.xyz, c.xyz);
  p.seed = 7;
  p.noise_seed = 1;  // same layout, other noise
  const GeneratedScan d = generateScene(p);
  EXPECT_GT(a.size(), 0u);
  EXPECT_NE(a.xyz, d.xyz);
}

TEST(SceneGenerator, LidarScanLooksLikeAnHdl64Frame) {
  SceneParams p;
  const GeneratedScan s = generateScene(p);
  expectConsistentSizes(s);
  // 64 x 1800 rays; most hit something within 80 m.
  EXPECT_GT(s.size(), 80000u);
  EXPECT_LE(s.size(), 64u * 1800u);
  const Counts c = count(p, s, p.curb_height + 6.0 * p.range_noise_sigma);
  EXPECT_EQ(c.nonfinite, 0u);
  const double ground_share = static_cast<double>(c.ground) / s.size();
  EXPECT_GT(ground_share, 0.30);
  EXPECT_LT(ground_share, 0.80);
  EXPECT_EQ(c.ground_off_surface, 0u);
  EXPECT_GT(c.nonground_above_1m, 1000u);  // walls, poles, trees
  for (std::size_t i = 0; i < s.size(); ++i) {
    ASSERT_LT(s.ring[i], 64);
    ASSERT_GE(s.intensity[i], 0.f);
    ASSERT_LE(s.intensity[i], 1.f);
    const double r = std::sqrt(s.xyz[3 * i] * s.xyz[3 * i] + s.xyz[3 * i + 1] * s.xyz[3 * i + 1] +
                               s.xyz[3 * i + 2] * s.xyz[3 * i + 2]);
    ASSERT_LT(r, p.lidar_max_range + 1.0);
  }
}

TEST(SceneGenerator, GroundTruthFollowsTheTerrainWithoutNoise) {
  SceneParams p;
  p.range_noise_sigma = 0.0;
  p.sensor_x = 12.0;  // on the way to the ramp: the lower level, the ramp and the upper level
  const GeneratedScan s = generateScene(p);
  // Exact surface: ground points are on it up to float rounding, except on the curb face.
  std::size_t on_surface = 0, on_ramp = 0, on_sidewalk = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s.truth[i] != 1) continue;
    const double x = s.xyz[3 * i], y = s.xyz[3 * i + 1];
    const double dz = s.xyz[3 * i + 2] - sceneGroundHeight(p, x, y);
    ASSERT_LE(std::fabs(dz), p.curb_height + 1e-3) << "ground point " << i;
    if (std::fabs(dz) < 2e-3) ++on_surface;
    const double wx = x + p.sensor_x;
    if (wx > p.ramp_start_x + 1.0 && wx < p.ramp_end_x - 1.0) ++on_ramp;
    if (y > p.curb_y + 0.5) ++on_sidewalk;
  }
  const Counts c = count(p, s, p.curb_height + 1e-3);
  EXPECT_GT(on_surface, c.ground * 99 / 100);  // only the curb face is off the height function
  EXPECT_GT(on_ramp, 1000u);
  EXPECT_GT(on_sidewalk, 1000u);
  // The canopy of the tree near the scanner overhangs the road.
  EXPECT_GT(c.canopy_over_road, 0u);
}

TEST(SceneGenerator, MovingTheScannerChangesTheScanButNotTheWorld) {
  SceneParams a;
  SceneParams b = a;
  b.sensor_x = 5.0;
  const GeneratedScan sa = generateScene(a);
  const GeneratedScan sb = generateScene(b);
  EXPECT_NE(sa.xyz, sb.xyz);
  // The same world point seen from both poses: the heights differ only by how much the terrain
  // (and so the scanner, which keeps its height above it) rises between the two poses.
  const double rise = sceneGroundHeight(a, 5.0, 0.0) - sceneGroundHeight(a, 0.0, 0.0);
  EXPECT_NEAR(rise, 5.0 * a.slope_x, 1e-9);
  EXPECT_NEAR(sceneGroundHeight(a, 10.0, 1.0) - sceneGroundHeight(b, 5.0, 1.0), rise, 1e-9);
  // Sensor height above the terrain below it.
  EXPECT_NEAR(sceneGroundHeight(a, 0.0, 0.0), -a.sensor_height, 1e-9);
}

TEST(SceneGenerator, TlsRespectsThePointBudget) {
  for (std::size_t budget : {20000u, 300000u}) {
    SceneParams p;
    p.mode = SceneParams::Mode::kTls;
    p.tls_points = budget;
    const GeneratedScan s = generateScene(p);
    expectConsistentSizes(s);
    EXPECT_LE(s.size(), budget);
    EXPECT_GE(s.size(), budget * 9 / 10) << "the ray grid is sized to fill the budget";
    const Counts c = count(p, s, p.curb_height + 6.0 * p.range_noise_sigma);
    EXPECT_EQ(c.nonfinite, 0u);
    EXPECT_EQ(c.ground_off_surface, 0u);
    const double ground_share = static_cast<double>(c.ground) / s.size();
    EXPECT_GT(ground_share, 0.30);
    EXPECT_LT(ground_share, 0.80);
    EXPECT_GT(c.nonground_above_1m, budget / 20);
    EXPECT_GT(c.canopy_over_road, 0u);  // the TLS sees the crowns from below
  }
}

TEST(SceneGenerator, TlsIsDeterministic) {
  SceneParams p;
  p.mode = SceneParams::Mode::kTls;
  p.tls_points = 50000;
  const GeneratedScan a = generateScene(p);
  const GeneratedScan b = generateScene(p);
  EXPECT_EQ(a.xyz, b.xyz);
  EXPECT_EQ(a.truth, b.truth);
}

TEST(SceneGenerator, NanPointsAreInsertedAsNonGround) {
  SceneParams p;
  p.beams = 16;
  p.azimuth_steps = 360;
  const GeneratedScan clean = generateScene(p);
  p.nan_points = 25;
  const GeneratedScan s = generateScene(p);
  expectConsistentSizes(s);
  ASSERT_EQ(s.size(), clean.size() + 25);
  std::size_t nan = 0, ground = 0, clean_ground = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (std::isnan(s.xyz[3 * i])) {
      ++nan;
      EXPECT_EQ(s.truth[i], 0);
    }
    ground += s.truth[i];
  }
  for (std::uint8_t t : clean.truth) clean_ground += t;
  EXPECT_EQ(nan, 25u);
  EXPECT_EQ(ground, clean_ground);     // no valid point lost
  EXPECT_FALSE(std::isnan(s.xyz[0]));  // spread inside the scan, not at its start
}

TEST(SceneGenerator, StreetClassesMatchTheTruth) {
  SceneParams p;
  p.beams = 32;
  p.azimuth_steps = 900;
  const GeneratedScan s = generateScene(p);
  ASSERT_EQ(s.semantic.size(), s.size());
  std::size_t road = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const bool ground_class = s.semantic[i] == kClassRoad || s.semantic[i] == kClassSidewalk;
    ASSERT_EQ(s.truth[i] == 1, ground_class) << "point " << i << " class " << s.semantic[i];
    road += s.semantic[i] == kClassRoad;
  }
  EXPECT_GT(road, s.size() / 5);
}

// The failure-mode layouts: exact truth (ground = the height field up to range noise and
// grass roughness; classes match the truth), bushes and undergrowth close to the ground.
struct LayoutCase {
  SceneParams::Layout layout;
  std::uint16_t must_have[3];
};

class NaturalLayout : public testing::TestWithParam<LayoutCase> {};

TEST_P(NaturalLayout, TruthIsExactAndTheFailureModesArePresent) {
  SceneParams p;
  p.layout = GetParam().layout;
  p.uniform_beams = true;
  p.vertical_min_deg = -16.6;
  p.vertical_max_deg = 16.6;
  p.azimuth_steps = 1024;
  p.sensor_height = 1.3;
  p.range_noise_sigma = 0.0;  // only the grass roughness moves ground points off the surface
  const GeneratedScan s = generateScene(p);
  expectConsistentSizes(s);
  ASSERT_EQ(s.semantic.size(), s.size());
  ASSERT_GT(s.size(), 20000u);
  std::map<std::uint16_t, std::size_t> per_class;
  std::size_t ground = 0, rough = 0, low_vegetation = 0;
  double max_grass_dz = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const std::uint16_t c = s.semantic[i];
    ++per_class[c];
    const bool ground_class =
        c == kClassRoad || c == kClassSidewalk || c == kClassOtherGround || c == kClassTerrain;
    ASSERT_EQ(s.truth[i] == 1, ground_class) << "point " << i << " class " << c;
    const double dz = s.xyz[3 * i + 2] - sceneGroundHeight(p, s.xyz[3 * i], s.xyz[3 * i + 1]);
    if (s.truth[i] == 1) {
      ++ground;
      // Kerb face (kVerge) and roughness; nothing else leaves the surface.
      const double tol = c == kClassSidewalk ? 0.13 : p.grass_roughness + 1e-3;
      ASSERT_LE(std::fabs(dz), tol) << "ground point " << i << " class " << c;
      if (c == kClassTerrain) {
        max_grass_dz = std::max(max_grass_dz, std::fabs(dz));
        rough += std::fabs(dz) > 0.02;
      }
    } else if (c == kClassVegetation && dz < 1.0) {
      ++low_vegetation;  // bushes and undergrowth: non-ground at any height
    }
  }
  for (std::uint16_t c : GetParam().must_have) EXPECT_GT(per_class[c], 500u) << "class " << c;
  EXPECT_GT(ground, s.size() / 4);
  EXPECT_GT(max_grass_dz, 0.8 * p.grass_roughness);  // the grass is noisy ...
  EXPECT_GT(rough, per_class[kClassTerrain] / 4);    // ... everywhere
  EXPECT_GT(low_vegetation, 1000u);
  EXPECT_EQ(generateScene(p).xyz, s.xyz);  // deterministic
}

INSTANTIATE_TEST_SUITE_P(
    Layouts, NaturalLayout,
    testing::Values(LayoutCase{SceneParams::Layout::kVerge,
                               {kClassRoad, kClassSidewalk, kClassTerrain}},
                    LayoutCase{SceneParams::Layout::kOffroad,
                               {kClassTerrain, kClassOtherGround, kClassVegetation}},
                    LayoutCase{SceneParams::Layout::kTrail,
                               {kClassTerrain, kClassOtherGround, kClassVegetation}}));

TEST(SceneGenerator, VergeSlopesAwayFromTheRoadAndTrailIsHilly) {
  SceneParams v;
  v.layout = SceneParams::Layout::kVerge;
  // Across the verge (world y 4 -> 7.5) the ground falls by 0.6-1.1 m; the far lawn rises.
  const double fall = sceneGroundHeight(v, 0.0, 4.0) - sceneGroundHeight(v, 0.0, 7.5);
  EXPECT_GT(fall, 0.5);
  EXPECT_LT(fall, 1.2);
  EXPECT_GT(sceneGroundHeight(v, 0.0, -14.0), sceneGroundHeight(v, 0.0, -6.0) + 0.8);
  SceneParams t;
  t.layout = SceneParams::Layout::kTrail;
  double lo = 1e9, hi = -1e9;
  for (double x = -40.0; x <= 40.0; x += 1.0) {
    const double z = sceneGroundHeight(t, x, 0.0);
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  EXPECT_GT(hi - lo, 2.0);  // metres of relief within 40 m
}

// Registered clouds: positions merged in the world frame (plus its offset), truth exact there;
// small variants of the built-in kinds (the sanitizer build runs this file).
TEST(SceneGenerator, RegisteredCloudsAreInTheWorldFrameWithExactTruth) {
  SceneParams mls = builtinSceneParams("mls");
  mls.positions = 3;
  mls.position_step = 10.0;
  mls.azimuth_steps = 360;
  mls.range_noise_sigma = 0.0;
  SceneParams far = builtinSceneParams("tls_far");
  far.tls_points = 20000;
  far.range_noise_sigma = 0.0;
  SceneParams uav = builtinSceneParams("uav");
  uav.crop_half_length = 10.0;
  uav.range_noise_sigma = 0.0;
  SceneParams slam = builtinSceneParams("slam");
  slam.positions = 3;
  slam.azimuth_steps = 256;
  slam.range_noise_sigma = 0.0;
  slam.grass_roughness = 0.0;
  SceneParams profiler = builtinSceneParams("profiler");
  profiler.crop_half_length = 5.0;
  profiler.range_noise_sigma = 0.0;
  for (const SceneParams* p : {&mls, &far, &uav, &slam, &profiler}) {
    SCOPED_TRACE(p == &mls    ? "mls"
                 : p == &far  ? "tls_far"
                 : p == &uav  ? "uav"
                 : p == &slam ? "slam"
                              : "profiler");
    EXPECT_TRUE(sceneInWorldFrame(*p));
    const GeneratedScan s = generateScene(*p);
    expectConsistentSizes(s);
    const Counts c = count(*p, s, p->curb_height + 2e-3);
    EXPECT_GT(c.ground, 1000u);
    EXPECT_GT(c.nonground_above_1m, 100u);
    EXPECT_EQ(c.ground_off_surface, 0u);  // exact terrain in the world frame, offset included
  }
  // The positions are merged: more points than one of them, spread along x by the steps.
  SceneParams one = mls;
  one.positions = 1;
  const GeneratedScan a = generateScene(one), b = generateScene(mls);
  EXPECT_GT(b.size(), 2 * a.size());
  float lo = 1e9f, hi = -1e9f;
  for (std::size_t i = 0; i < b.size(); ++i) {
    if (b.truth[i] != 1) continue;
    lo = std::min(lo, b.xyz[3 * i]);
    hi = std::max(hi, b.xyz[3 * i]);
  }
  EXPECT_GT(hi - lo, 2 * mls.position_step);
  // The far station sits around its offset; the UAV sees down only (every point below it).
  const GeneratedScan f = generateScene(far);
  double mx = 0.0;
  for (std::size_t i = 0; i < f.size(); ++i) mx += f.xyz[3 * i];
  EXPECT_NEAR(mx / f.size(), far.world_offset_x, 60.0);
  const GeneratedScan u = generateScene(uav);
  for (std::size_t i = 0; i < u.size(); ++i) {
    ASSERT_LT(u.xyz[3 * i + 2], sceneGroundHeight(uav, u.xyz[3 * i], u.xyz[3 * i + 1]) + 30.0);
  }
  // The profile scanner sees every direction of its plane: facades and crowns above it too, on
  // both sides of the street, and its profiles lie 0.1 m apart along x.
  const GeneratedScan pr = generateScene(profiler);
  std::size_t above = 0, left = 0, right = 0;
  for (std::size_t i = 0; i < pr.size(); ++i) {
    const float x = pr.xyz[3 * i], y = pr.xyz[3 * i + 1], z = pr.xyz[3 * i + 2];
    if (z > sceneGroundHeight(profiler, x, y) + 3.0) ++above;
    (y > profiler.sensor_y ? left : right) += 1;
    ASSERT_LE(std::fabs(x), profiler.crop_half_length + 1e-3);
  }
  EXPECT_GT(above, pr.size() / 20);
  EXPECT_GT(std::min(left, right), pr.size() / 5);
  // Past 90 deg its near-horizontal rays still reach terrain far across the track.
  for (double half : {91.0, 95.0, 180.0}) {
    profiler.uav_half_angle_deg = half;
    const GeneratedScan h = generateScene(profiler);
    double reach = 0.0;
    for (std::size_t i = 0; i < h.size(); ++i)
      if (h.truth[i] == 1) reach = std::max(reach, std::fabs(h.xyz[3 * i + 1] - profiler.sensor_y));
    EXPECT_GT(reach, 40.0) << half;
  }
  SceneParams bad = mls;
  bad.position_keep = 0.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(SceneGenerator, BuiltinKindsNameTheirSceneAndScanner) {
  EXPECT_EQ(builtinSceneKinds().size(), 17u);
  for (const std::string& kind : builtinSceneKinds()) {
    EXPECT_NO_THROW(builtinSceneParams(kind).validate()) << kind;
  }
  EXPECT_EQ(builtinSceneParams("tls").mode, SceneParams::Mode::kTls);
  EXPECT_EQ(builtinSceneParams("verge").layout, SceneParams::Layout::kVerge);
  const SceneParams ouster = builtinSceneParams("trail");
  EXPECT_EQ(ouster.layout, SceneParams::Layout::kTrail);
  EXPECT_TRUE(ouster.uniform_beams);
  EXPECT_EQ(ouster.azimuth_steps, 2048);
  EXPECT_EQ(builtinSceneParams("offroad").layout, SceneParams::Layout::kOffroad);
  try {
    builtinSceneParams("moon");
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("trail"), std::string::npos) << e.what();
  }
}

// kGarage: the floor is the ground (on sceneGroundHeight, the scanner 1.8 m over it), a
// ceiling ceiling_height over the floor covers the level and is seen from below (a large share
// of the returns, all non-ground), and a ceiling lower than 1.5 m is refused by name.
TEST(SceneGenerator, GarageHasAFloorAndACeilingOverIt) {
  SceneParams p = builtinSceneParams("garage");
  EXPECT_EQ(p.layout, SceneParams::Layout::kGarage);
  const GeneratedScan g = generateScene(p);
  std::size_t floor = 0, ceiling = 0;
  for (std::size_t i = 0; i < g.size(); ++i) {
    const float* q = &g.xyz[3 * i];
    if (!std::isfinite(q[2])) continue;
    if (g.truth[i] == 1) {
      ++floor;
      ASSERT_NEAR(q[2], sceneGroundHeight(p, q[0], q[1]), 0.15) << i;
      ASSERT_NEAR(q[2], -p.sensor_height, 0.15) << i;
      ASSERT_EQ(g.semantic[i], kClassRoad);
    } else if (std::fabs(q[2] - (p.ceiling_height - p.sensor_height)) < 0.1) {
      ++ceiling;
      ASSERT_EQ(g.semantic[i], kClassBuilding);
    }
  }
  EXPECT_GT(floor, g.size() / 5);
  EXPECT_GT(ceiling, g.size() / 5);
  p.ceiling_height = 1.0;
  try {
    p.validate();
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ceiling_height"), std::string::npos) << e.what();
  }
}

// kAirborne: one return per pulse at the requested density, truth = terrain class exactly,
// ground points on sceneGroundHeight (within the noise), objects above it, and the embankment
// and hills give metres of relief.
TEST(SceneGenerator, AirborneTileHasExactTruthAndRelief) {
  SceneParams p = builtinSceneParams("airborne");
  EXPECT_EQ(p.mode, SceneParams::Mode::kAirborne);
  p.seed = 3;
  const GeneratedScan a = generateScene(p);
  const double area = 4.0 * p.scene_extent * p.scene_extent;
  EXPECT_NEAR(static_cast<double>(a.size()), area * p.airborne_density, 0.02 * area);
  std::map<std::uint16_t, std::size_t> classes;
  double lo = 1e9, hi = -1e9;
  std::size_t ground = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const float* q = &a.xyz[3 * i];
    const double surface = sceneGroundHeight(p, q[0], q[1]);
    ++classes[a.semantic[i]];
    ASSERT_EQ(a.truth[i], a.semantic[i] == kClassTerrain ? 1 : 0) << i;
    if (a.truth[i]) {
      ++ground;
      ASSERT_NEAR(q[2], surface, 6 * p.range_noise_sigma) << i;
      lo = std::min(lo, surface);
      hi = std::max(hi, surface);
    } else {
      ASSERT_GT(q[2], surface - 6 * p.range_noise_sigma) << i;
    }
  }
  EXPECT_GT(hi - lo, 8.0);
  EXPECT_GT(ground, a.size() / 2);
  EXPECT_GT(classes[kClassBuilding], 1000u);
  EXPECT_GT(classes[kClassVegetation], 1000u);
  EXPECT_GT(classes[kClassCar], 20u);
  const GeneratedScan b = generateScene(p);
  EXPECT_EQ(a.xyz, b.xyz);  // deterministic
}

TEST(SceneGenerator, AirborneHallIsOneRoofWiderThanTheOpening) {
  SceneParams p = builtinSceneParams("airborne");
  p.seed = 1;
  p.airborne_hall = 80.0;
  const GeneratedScan a = generateScene(p);
  // Every return over the hall's footprint (away from its edges) hits its flat roof, 8 m above
  // the highest terrain under it, unless a higher crown hides it.
  std::size_t inside = 0, roof = 0;
  double roof_lo = 1e9, roof_hi = -1e9;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const float* q = &a.xyz[3 * i];
    if (std::fabs(q[0]) >= 38.0 || std::fabs(q[1]) >= 38.0) continue;
    ++inside;
    EXPECT_EQ(a.truth[i], 0) << i;
    if (a.semantic[i] != kClassBuilding) continue;
    ++roof;
    roof_lo = std::min(roof_lo, static_cast<double>(q[2]));
    roof_hi = std::max(roof_hi, static_cast<double>(q[2]));
  }
  EXPECT_NEAR(static_cast<double>(inside), 76.0 * 76.0 * p.airborne_density, 0.05 * inside);
  EXPECT_GT(roof, inside * 9 / 10);
  EXPECT_LT(roof_hi - roof_lo, 10 * p.range_noise_sigma);  // one flat roof
  p.airborne_hall = -1.0;
  EXPECT_THROW(generateScene(p), std::invalid_argument);
}

TEST(SceneGenerator, AirborneHallStepGivesARoofInThreeParts) {
  SceneParams p = builtinSceneParams("airborne");
  p.seed = 1;
  p.airborne_hall = 120.0;
  const GeneratedScan flat = generateScene(p);
  p.airborne_hall_step = 3.0;
  const GeneratedScan a = generateScene(p);
  // The roof's height per third along x (returns 2 m or more from its edges and seams): the
  // flat roof's, 3 m lower in the west third, 3 m higher in the centre.
  auto roofHeights = [](const GeneratedScan& s, double out[3]) {
    std::size_t count[3] = {0, 0, 0};
    for (int t = 0; t < 3; ++t) out[t] = 0.0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      const float* q = &s.xyz[3 * i];
      if (s.semantic[i] != kClassBuilding || std::fabs(q[0]) > 58.f || std::fabs(q[1]) > 58.f ||
          std::fabs(std::fabs(q[0]) - 20.f) < 2.f) {
        continue;
      }
      const int t = q[0] < -20.f ? 0 : (q[0] < 20.f ? 1 : 2);
      out[t] += q[2];
      ++count[t];
    }
    for (int t = 0; t < 3; ++t) out[t] = count[t] > 500 ? out[t] / count[t] : 1e9;
  };
  double h_flat[3], h[3];
  roofHeights(flat, h_flat);
  roofHeights(a, h);
  for (int t = 0; t < 3; ++t) EXPECT_NEAR(h_flat[t], h_flat[2], 0.05) << t;
  EXPECT_NEAR(h[0], h_flat[2] - 3.0, 0.05);
  EXPECT_NEAR(h[1], h_flat[2] + 3.0, 0.05);
  EXPECT_NEAR(h[2], h_flat[2], 0.05);
  for (const double bad : {-0.5, 6.5}) {
    p.airborne_hall_step = bad;
    EXPECT_THROW(generateScene(p), std::invalid_argument) << bad;
  }
}

TEST(SceneGenerator, InvalidParametersAreRefused) {
  SceneParams p;
  p.mode = SceneParams::Mode::kTls;
  p.tls_points = 200000000;  // over the 100 M budget
  EXPECT_THROW(generateScene(p), std::invalid_argument);
  SceneParams q;
  q.beams = 0;
  EXPECT_THROW(generateScene(q), std::invalid_argument);
  SceneParams r;
  r.ramp_end_x = r.ramp_start_x - 1.0;
  EXPECT_THROW(generateScene(r), std::invalid_argument);
  SceneParams s;
  s.range_noise_sigma = -0.1;
  EXPECT_THROW(generateScene(s), std::invalid_argument);
  SceneParams g;
  g.grass_roughness = -0.01;
  EXPECT_THROW(generateScene(g), std::invalid_argument);
  SceneParams e;
  e.second_returns = 1.5;
  EXPECT_THROW(generateScene(e), std::invalid_argument);
}

// base_frame: the same scan with the sensor's height added to every z (the frame on the ground
// below it, as a robot's base_link); the true terrain moves with it; not for merged clouds.
TEST(SceneGenerator, BaseFrameIsTheScanMovedUpByTheSensorHeight) {
  const SceneParams ps = parseSceneSpec("lidar16:1:layout=trail,sensor_height=1.8");
  const SceneParams pb = parseSceneSpec("lidar16:1:layout=trail,sensor_height=1.8,base_frame=1");
  const GeneratedScan s = generateScene(ps), b = generateScene(pb);
  ASSERT_EQ(s.size(), b.size());
  for (std::size_t i = 0; i < s.size(); i += 97) {
    EXPECT_EQ(s.xyz[3 * i], b.xyz[3 * i]);
    EXPECT_NEAR(b.xyz[3 * i + 2] - s.xyz[3 * i + 2], 1.8, 1e-4) << i;
  }
  EXPECT_NEAR(sceneGroundHeight(pb, 0.0, 0.0), 0.0, 1e-9);
  EXPECT_NEAR(sceneGroundHeight(ps, 0.0, 0.0), -1.8, 1e-9);
  EXPECT_NEAR(sceneGroundHeight(pb, 12.0, -5.0) - sceneGroundHeight(ps, 12.0, -5.0), 1.8, 1e-9);
  EXPECT_THROW(generateScene(parseSceneSpec("lidar16:1:positions=2,base_frame=1")),
               std::invalid_argument);
}

// mount_roll_deg / mount_pitch_deg: the level scan's points in a frame rolled, then pitched
// (> 0 tips x down); its frame has no vertical (no terrain height); one scan only.
TEST(SceneGenerator, TiltedMountIsTheLevelScanTurned) {
  const GeneratedScan s = generateScene(parseSceneSpec("lidar16:1"));
  const SceneParams pt = parseSceneSpec("lidar16:1:mount_roll_deg=10,mount_pitch_deg=20");
  const GeneratedScan t = generateScene(pt);
  ASSERT_EQ(s.size(), t.size());
  const double r = 10.0 * M_PI / 180.0, p = 20.0 * M_PI / 180.0;
  for (std::size_t i = 0; i < s.size(); i += 89) {
    // Back to the level frame: p_level = Ry(pitch) Rx(roll) p_tilted.
    const double x = t.xyz[3 * i], y = t.xyz[3 * i + 1], z = t.xyz[3 * i + 2];
    const double y1 = std::cos(r) * y - std::sin(r) * z, z1 = std::sin(r) * y + std::cos(r) * z;
    const double x2 = std::cos(p) * x + std::sin(p) * z1, z2 = -std::sin(p) * x + std::cos(p) * z1;
    EXPECT_NEAR(x2, s.xyz[3 * i], 1e-4) << i;
    EXPECT_NEAR(y1, s.xyz[3 * i + 1], 1e-4) << i;
    EXPECT_NEAR(z2, s.xyz[3 * i + 2], 1e-4) << i;
    EXPECT_EQ(s.truth[i], t.truth[i]);
  }
  // Pitched down, the ground ahead rises in the sensor's frame.
  const GeneratedScan down = generateScene(parseSceneSpec("lidar16:1:mount_pitch_deg=10"));
  for (std::size_t i = 0; i < s.size(); i += 89) {
    if (s.truth[i] == 1 && s.xyz[3 * i] > 10.f) EXPECT_GT(down.xyz[3 * i + 2], s.xyz[3 * i + 2]);
  }
  EXPECT_TRUE(std::isnan(sceneGroundHeight(pt, 1.0, 2.0)));
  EXPECT_THROW(generateScene(parseSceneSpec("lidar16:1:positions=2,mount_roll_deg=5")),
               std::invalid_argument);
  EXPECT_NO_THROW(generateScene(parseSceneSpec("lidar16:1:mount_pitch_deg=90")));
  EXPECT_THROW(generateScene(parseSceneSpec("lidar16:1:mount_pitch_deg=95")),
               std::invalid_argument);
  EXPECT_THROW(generateScene(parseSceneSpec("lidar16:1:mount_roll_deg=-91")),
               std::invalid_argument);
}

// A dual-return sensor: each point the scan without them lacks is a second echo of a beam
// whose first echo was foliage, on the same ray 1 m or more farther out, right after it.
TEST(SceneGenerator, SecondEchoesFollowTheirFoliageOnTheSameRay) {
  const GeneratedScan one = generateScene(parseSceneSpec("offroad:1"));
  const GeneratedScan two = generateScene(parseSceneSpec("offroad:1:second_returns=0.5"));
  std::size_t j = 0, echoes = 0;
  for (std::size_t i = 0; i < two.size(); ++i) {
    if (j < one.size() && std::equal(&two.xyz[3 * i], &two.xyz[3 * i + 3], &one.xyz[3 * j])) {
      ++j;
      continue;
    }
    ASSERT_GT(i, 0u);
    ++echoes;
    EXPECT_EQ(two.semantic[i - 1], kClassVegetation) << i;
    EXPECT_EQ(two.ring[i], two.ring[i - 1]) << i;
    const float* a = &two.xyz[3 * (i - 1)];
    const float* b = &two.xyz[3 * i];
    const double ra = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    const double rb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    EXPECT_GT(rb, ra + 0.8) << i;  // 1 m apart, less the range noise and grass roughness
    // The same direction, but for the noise (0.05 m grass roughness at 5 m and more: 0.01).
    const double cosine = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (ra * rb);
    EXPECT_GT(cosine, 1.0 - 1e-3) << i;
  }
  EXPECT_EQ(j, one.size());
  EXPECT_GT(echoes, one.size() / 20);
  EXPECT_EQ(two.truth.size(), two.size());
}

// A solid-state sensor's frame: every return inside its forward disc, exact ground heights, no
// two rays alike (the pattern does not repeat within a frame).
TEST(SceneGenerator, RosetteIsAForwardDiscOfNonRepeatingRays) {
  SceneParams p = builtinSceneParams("rosette");
  p.range_noise_sigma = 0.0;
  const GeneratedScan s = generateScene(p);
  ASSERT_GT(s.size(), p.rosette_rays / 2);  // most rays hit the street
  ASSERT_LE(s.size(), p.rosette_rays);
  const double half = 0.5 * p.rosette_fov_deg * M_PI / 180.0;
  std::size_t ground = 0, off_surface = 0;
  std::map<std::pair<int, int>, int> directions;  // 0.01 deg bins
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double x = s.xyz[3 * i], y = s.xyz[3 * i + 1], z = s.xyz[3 * i + 2];
    const double az = std::atan2(y, x), el = std::atan2(z, std::hypot(x, y));
    EXPECT_LE(std::hypot(az, el), half + 1e-6) << i;  // the deflection (azimuth, elevation)
    ++directions[{static_cast<int>(std::lround(az * 18000.0 / M_PI)),
                  static_cast<int>(std::lround(el * 18000.0 / M_PI))}];
    if (s.truth[i] != 1) continue;
    ++ground;
    off_surface += std::fabs(z - sceneGroundHeight(p, x, y)) > 0.01;  // only the curb's face
  }
  EXPECT_GT(ground, s.size() / 4);
  EXPECT_LT(off_surface, ground / 50);
  EXPECT_GT(directions.size(), s.size() * 9 / 10);
}

// builtin:KIND[:SEED][:NAME=VALUE,...] of the tools (scripts/sensor_sweep.py's sensors).
TEST(SceneGenerator, SceneSpecSetsTheSeedAndNamedFields) {
  const SceneParams p = parseSceneSpec("lidar16:7:layout=trail,beams=32,sensor_height=1.2");
  EXPECT_EQ(p.seed, 7u);
  EXPECT_EQ(p.layout, SceneParams::Layout::kTrail);
  EXPECT_EQ(p.beams, 32);
  EXPECT_DOUBLE_EQ(p.sensor_height, 1.2);
  EXPECT_EQ(p.azimuth_steps, builtinSceneParams("lidar16").azimuth_steps);       // the kind's own
  const SceneParams q = parseSceneSpec("tls:uniform_beams=on,tls_points=5000");  // no seed
  EXPECT_EQ(q.seed, 1u);
  EXPECT_TRUE(q.uniform_beams);
  EXPECT_EQ(q.tls_points, 5000u);
  EXPECT_EQ(parseSceneSpec("offroad").beams, builtinSceneParams("offroad").beams);
  // Every listed field is settable.
  for (const std::string& name : sceneOverrideNames()) {
    const std::string value =
        name == "layout"                                                           ? "verge"
        : name == "uniform_beams" || name == "base_frame" || name == "world_frame" ? "1"
                                                                                   : "3";
    EXPECT_NO_THROW(parseSceneSpec("lidar:1:" + name + "=" + value)) << name;
  }
}

TEST(SceneGenerator, SceneSpecRefusesUnknownFieldsAndBadValuesByName) {
  auto message = [](const std::string& spec) {
    try {
      parseSceneSpec(spec);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("lidar16:1:beam=3").find("unknown scene field 'beam'"), std::string::npos);
  EXPECT_NE(message("lidar16:1:beams=x").find("'beams'"), std::string::npos);
  EXPECT_NE(message("lidar16:1:layout=moon").find("layout"), std::string::npos);
  EXPECT_NE(message("lidar16:1:tls_points=2.5").find("whole number"), std::string::npos);
  EXPECT_NE(message("lidar16:1:beams").find("NAME=VALUE"), std::string::npos);
  EXPECT_NE(message("lidar16:x1").find("seed"), std::string::npos);
  EXPECT_NE(message("lidar17").find("unknown built-in scene"), std::string::npos);
  // Ranges are checked where the scene is made.
  EXPECT_THROW(generateScene(parseSceneSpec("lidar16:1:beams=2000")), std::invalid_argument);
}

}  // namespace
}  // namespace ground_filter

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
