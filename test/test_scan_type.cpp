// scan_type: the per-scan decision between a ground-level scan and an airborne one (generated
// scenes of each kind, the hard cases, bad input), what it switches, and the working volume's
// max_range, which must not cut an airborne tile.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "airborne/scan_type.h"
#include "eval/metrics.h"
#include "eval/scene_generator.h"
#include "gf_test_alloc_counter.h"  // allocationCount()
#include "ground_filter/ground_filter.h"
#include "ground_filter/voxel_ground_filter.h"
#include "ground_filter/working_volume.h"

namespace gf = ground_filter;

namespace {

struct Cloud {
  std::vector<float> xyz;
  std::vector<std::uint8_t> truth;
  std::size_t size() const { return xyz.size() / 3; }
  gf::CloudView view() const { return gf::CloudView::packedXyz(xyz.data(), size()); }
  void add(float x, float y, float z, bool ground) {
    xyz.insert(xyz.end(), {x, y, z});
    truth.push_back(ground ? 1 : 0);
  }
};

Cloud generated(const gf::SceneParams& p) {
  const gf::GeneratedScan s = gf::generateScene(p);
  return {s.xyz, s.truth};
}

Cloud builtin(const std::string& kind, std::uint32_t seed = 1) {
  gf::SceneParams p = gf::builtinSceneParams(kind);
  p.seed = seed;
  if (kind == "tls") p.tls_points = 200000;  // the decision needs no 2 M points
  return generated(p);
}

// A nadir drone scan: the generated airborne world seen from `height` m above the terrain at
// the tile's centre with a +-35 deg field of view (a Livox-like UAV LiDAR), in the sensor frame.
Cloud drone(double height, double density, std::uint32_t seed = 1) {
  gf::SceneParams p = gf::builtinSceneParams("airborne");
  p.seed = seed;
  p.scene_extent = std::max(12.0, height * std::tan(35.0 * M_PI / 180.0) + 2.0);
  p.airborne_density = density;
  const Cloud world = generated(p);
  const double z0 = gf::sceneGroundHeight(p, 0.0, 0.0) + height;
  const double reach = height * std::tan(35.0 * M_PI / 180.0);
  Cloud c;
  for (std::size_t i = 0; i < world.size(); ++i) {
    const float x = world.xyz[3 * i], y = world.xyz[3 * i + 1], z = world.xyz[3 * i + 2];
    if (std::hypot(x, y) > reach) continue;
    c.add(x, y, static_cast<float>(z - z0), world.truth[i]);
  }
  return c;
}

// A car on a bridge: an HDL-64-like scanner 1.8 m above a 10 m wide deck (railings 1 m high)
// that crosses a valley 12 m below the deck; the scanner frame.
Cloud bridge() {
  Cloud c;
  const double deck = -1.8, valley = -13.8, half = 5.0, rail_top = deck + 1.0, reach = 100.0;
  for (int b = 0; b < 64; ++b) {
    const double e = (-24.8 + b * (26.8 / 63.0)) * M_PI / 180.0;
    for (int a = 0; a < 1800; ++a) {
      const double az = a * 2.0 * M_PI / 1800.0;
      const double dx = std::cos(e) * std::cos(az), dy = std::cos(e) * std::sin(az),
                   dz = std::sin(e);
      if (dz >= 0.0) continue;  // sky
      const double t_deck = deck / dz;
      const double t_rail = std::fabs(dy) > 1e-9 ? half / std::fabs(dy) : 1e9;
      if (t_rail < t_deck && dz * t_rail <= rail_top && t_rail <= reach) {
        c.add(static_cast<float>(dx * t_rail), static_cast<float>(dy * t_rail),
              static_cast<float>(dz * t_rail), false);
      } else if (std::fabs(dy * t_deck) <= half && t_deck <= reach) {
        c.add(static_cast<float>(dx * t_deck), static_cast<float>(dy * t_deck),
              static_cast<float>(deck), true);
      } else if (valley / dz <= reach) {
        const double t = valley / dz;
        c.add(static_cast<float>(dx * t), static_cast<float>(dy * t), static_cast<float>(valley),
              true);
      }
    }
  }
  return c;
}

gf::ScanDecision classify(const Cloud& c, float ox = 0.f, float oy = 0.f, float oz = 0.f) {
  gf::ScanTypeClassifier k;
  const float o[3] = {ox, oy, oz};
  gf::ScanDecision d;
  k.classify(c.view(), o, &d);
  return d;
}

double topShare(const Cloud& c) {
  gf::ScanTypeClassifier k;
  const float o[3] = {0.f, 0.f, 0.f};
  return k.measure(c.view(), o).top_share;
}

// Runs `method` (through makeGroundFilter) and checks the contract: one 0/1 label per point,
// a scan type and a reason in the stats.
gf::FilterStats runChecked(const std::string& method, const Cloud& c,
                           std::vector<std::uint8_t>* labels, gf::ParamSettings settings = {}) {
  if (method == "normal") settings.push_back({"threads", "2"});
  auto f = gf::makeGroundFilter(method, settings);
  gf::FilterStats st;
  f->filter(c.view(), labels, &st);
  EXPECT_EQ(labels->size(), c.size());
  for (std::uint8_t l : *labels) EXPECT_TRUE(l == 0 || l == 1);
  EXPECT_FALSE(st.scan_type.empty());
  EXPECT_FALSE(st.scan_reason.empty());
  return st;
}

double f1(const std::vector<std::uint8_t>& labels, const Cloud& c) {
  const std::vector<std::int8_t> truth(c.truth.begin(), c.truth.end());
  return gf::computeMetrics(gf::countConfusion(labels, truth)).f1;
}

}  // namespace

// ---------------------------------------------------------------- the decision, per scan kind

TEST(ScanType, VehicleScansAreGroundLevel) {
  for (const char* kind : {"lidar", "verge", "offroad", "trail"}) {
    for (std::uint32_t seed : {1u, 3u}) {
      SCOPED_TRACE(std::string(kind) + ":" + std::to_string(seed));
      const Cloud c = builtin(kind, seed);
      const gf::ScanDecision d = classify(c);
      EXPECT_EQ(d.type, gf::ScanType::kGround) << d.reason;
      // Margin to the rule's 40 %: far from the cut on either side (plateau).
      EXPECT_GE(topShare(c), 0.5);
      // One viewpoint: next to nothing lies behind nearer points (the normal method's cut for
      // a merged cloud is 0.06, OriginView).
      const float o[3] = {0.f, 0.f, 0.f};
      EXPECT_LT(gf::ScanTypeClassifier().measure(c.view(), o).hidden_share, 0.03);
    }
  }
}

// A spinning sensor's points are densest around it: its densest cell lies within about 10 m of
// it, and 40 m off in a frame whose origin lies elsewhere (the voxel method's start segment
// reads more than 20 m as "the origin is no sensor").
TEST(ScanType, DensestCellLiesAtTheSensor) {
  for (const char* spec : {"lidar16:1:layout=trail,sensor_height=1.2,sensor_x=40",
                           "lidar16:2:layout=street,beams=128,sensor_height=0.7,sensor_x=40"}) {
    SCOPED_TRACE(spec);
    for (int map = 0; map < 2; ++map) {
      const Cloud c =
          generated(gf::parseSceneSpec(std::string(spec) + (map ? ",world_frame=1" : "")));
      const double offset = classify(c).densest_offset;
      if (map) {
        EXPECT_NEAR(offset, 40.0, 10.0);
      } else {
        EXPECT_LT(offset, 10.0);
      }
    }
  }
}

TEST(ScanType, TlsStationIsGroundLevelTls) {
  const Cloud c = builtin("tls");
  const gf::ScanDecision d = classify(c);
  EXPECT_EQ(d.type, gf::ScanType::kTls) << d.reason;
  EXPECT_GE(topShare(c), 0.5);
}

TEST(ScanType, AirborneTileInItsWorldFrameIsAirborne) {
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    const Cloud c = builtin("airborne", seed);
    const gf::ScanDecision d = classify(c);
    EXPECT_EQ(d.type, gf::ScanType::kAirborne) << d.reason;
    EXPECT_LE(topShare(c), 0.3);
  }
}

TEST(ScanType, UavNadirSeenFromTheSensorIsAirborne) {
  const Cloud c = drone(60.0, 20.0);
  const gf::ScanDecision d = classify(c);
  EXPECT_EQ(d.type, gf::ScanType::kAirborne) << d.reason;
  // Both rules agree: even sampling, and the points lie far below, within 45 deg of nadir.
  gf::ScanTypeClassifier k;
  const float o[3] = {0.f, 0.f, 0.f};
  const gf::ScanMeasures m = k.measure(c.view(), o);
  EXPECT_GE(m.steep_share, 0.9);
  EXPECT_GE(m.steep_depth, 40.0);
  EXPECT_LE(m.top_share, 0.3);
  // And seen from above it is even at 1 m too: no side view (rule 4) overrides rule 2.
  EXPECT_GE(m.column_mean, gf::ScanTypeClassifier::kMinColumnMean);
  EXPECT_LE(m.column_top_share, 0.2);
}

TEST(ScanType, DroneFlyingLowOverTreesIsAirborne) {
  // 15 m above the ground: crowns of 5-18 m reach close to it (or above it).
  for (std::uint32_t seed : {1u, 2u}) {
    const Cloud c = drone(15.0, 60.0, seed);
    ASSERT_GT(c.size(), 1000u);
    const gf::ScanDecision d = classify(c);
    EXPECT_EQ(d.type, gf::ScanType::kAirborne) << d.reason;
  }
}

TEST(ScanType, VehicleOnABridgeIsGroundLevel) {
  const Cloud c = bridge();
  ASSERT_GT(c.size(), 50000u);
  const gf::ScanDecision d = classify(c);
  EXPECT_EQ(d.type, gf::ScanType::kGround) << d.reason;
  EXPECT_GE(topShare(c), 0.5);
  // The valley 12 m below does not make it airborne: the deck hides the view straight down.
  gf::ScanTypeClassifier k;
  const float o[3] = {0.f, 0.f, 0.f};
  EXPECT_LT(k.measure(c.view(), o).steep_share, 0.1);
}

TEST(ScanType, SteepTileIsAirborne) {
  gf::SceneParams p = gf::builtinSceneParams("airborne");
  Cloud c = generated(p);
  for (std::size_t i = 0; i < c.size(); ++i) c.xyz[3 * i + 2] += 0.7f * c.xyz[3 * i];  // 35 deg
  const gf::ScanDecision d = classify(c);
  EXPECT_EQ(d.type, gf::ScanType::kAirborne) << d.reason;
}

// Registered clouds (several sensor positions merged in one world frame, no sensor at the
// origin) are ground-level; nadir clouds of the same worlds, dense ones included, stay airborne.
TEST(ScanType, RegisteredCloudsAreGroundLevel) {
  struct Case {
    const char* kind;
    const char* rule;  // words of the reason line of the rule that must decide
  };
  const Case cases[] = {{"mls", "side view"},
                        {"mls_air", "side view"},
                        {"slam", "side view"},
                        {"stations", "density falls with range"},
                        {"tls_far", "map coordinates"}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.kind);
    const Cloud cloud = builtin(c.kind, 1);
    gf::ScanTypeClassifier k;
    const float o[3] = {0.f, 0.f, 0.f};
    gf::ScanDecision d;
    k.classify(cloud.view(), o, &d);
    EXPECT_NE(d.type, gf::ScanType::kAirborne) << d.reason;
    EXPECT_NE(d.reason.find(c.rule), std::string::npos) << d.reason;
    // The map frame's origin is no sensor position: no range cut for the side-view and far
    // decisions.
    if (std::string(c.kind) != "stations") EXPECT_TRUE(d.registered) << d.reason;
    const gf::ScanMeasures m = k.measure(cloud.view(), o);
    EXPECT_LE(m.read, gf::ScanTypeClassifier::kMaxRead);
    // Read as one scan, but seen from its first station much lies behind nearer points: no
    // sensor rule for its planes in the normal method (docs/normal_method.md, "Ceilings").
    if (std::string(c.kind) == "stations") EXPECT_GT(m.hidden_share, 0.12);
  }
}

TEST(ScanType, AProfileScannersStreetIsGroundLevel) {
  // A mobile-mapping van's profile scanner: every 0.1 m of travel one profile across the
  // track, registered in the world frame. Each profile sees the ground at its feet and the
  // facades beside it, so the cloud is neither one sweep whose density falls with range nor a
  // nadir view: it must not go to the airborne mode, and both methods must split it.
  for (const char* layout : {"street", "verge"}) {
    for (std::uint32_t seed : {1u, 2u}) {
      SCOPED_TRACE(std::string(layout) + ":" + std::to_string(seed));
      gf::SceneParams p = gf::builtinSceneParams("profiler");
      p.seed = seed;
      p.layout = std::string(layout) == "verge" ? gf::SceneParams::Layout::kVerge
                                                : gf::SceneParams::Layout::kStreet;
      p.crop_half_length = 12.0;  // 24 m of street: 241 profiles
      p.uav_angle_step_deg = 0.5;
      const Cloud c = generated(p);
      ASSERT_GT(c.size(), 80000u);
      const gf::ScanDecision d = classify(c);
      EXPECT_EQ(d.type, gf::ScanType::kGround) << d.reason;
      for (const char* method : {"voxel", "normal"}) {
        SCOPED_TRACE(method);
        std::vector<std::uint8_t> labels;
        runChecked(method, c, &labels, {});
        EXPECT_GT(f1(labels, c), 0.97);
      }
    }
  }
}

TEST(ScanType, NadirCloudsOfTheSameWorldsStayAirborne) {
  // uav: a line scanner 40 m over the street (+-35 deg: walls seen obliquely, 25 points per
  // 1 m column); corridor: a 30 m strip of the airborne tile; airborne:3, an unseen seed.
  for (const char* kind : {"uav", "corridor"}) {
    for (std::uint32_t seed : {1u, 2u}) {
      SCOPED_TRACE(std::string(kind) + ":" + std::to_string(seed));
      const gf::ScanDecision d = classify(builtin(kind, seed));
      EXPECT_EQ(d.type, gf::ScanType::kAirborne) << d.reason;
      EXPECT_FALSE(d.registered);
      EXPECT_NE(d.reason.find("1 m columns"), std::string::npos) << d.reason;
    }
  }
  EXPECT_EQ(classify(builtin("airborne", 3)).type, gf::ScanType::kAirborne);
}

TEST(ScanType, AMapTileFarBelowItsOriginIsGroundLevel) {
  // A SLAM map tile or a mobile-mapping run registered in a frame whose origin lies 20 or 40 m
  // above it (the map started uphill): seen from the origin, most points lie 45 deg or more below
  // it, as under a drone (rule 2), but the 1 m columns hold the side view of ground-level
  // sensors (rule 4). It was sent to the airborne mode (slam F1 0.82); it is ground-level.
  const struct {
    const char* kind;
    double below;  // m
  } cases[] = {{"slam", 20.0}, {"mls", 40.0}};
  for (const auto& t : cases) {
    SCOPED_TRACE(t.kind);
    gf::SceneParams p = gf::builtinSceneParams(t.kind);
    p.world_offset_z = -t.below;
    const Cloud c = generated(p);
    gf::ScanTypeClassifier k;
    const float o[3] = {0.f, 0.f, 0.f};
    const gf::ScanMeasures m = k.measure(c.view(), o);
    EXPECT_GE(m.steep_share, gf::ScanTypeClassifier::kSteepShare);
    EXPECT_GE(m.steep_depth, gf::ScanTypeClassifier::kNadirDepth);
    const gf::ScanDecision d = classify(c);
    EXPECT_EQ(d.type, gf::ScanType::kGround) << d.reason;
    EXPECT_TRUE(d.registered);
    EXPECT_NE(d.reason.find("side view"), std::string::npos) << d.reason;
    std::vector<std::uint8_t> labels;
    runChecked("voxel", c, &labels);
    EXPECT_GT(f1(labels, c), 0.88);
  }
}

TEST(ScanType, RegisteredCloudFarFromTheOriginIsNotCutByMaxRange) {
  // One TLS station exported 2.4 km from the origin: with the nodelets' max_range (1000 m) no
  // point is cut and the labels are those of the filter without a working volume.
  const Cloud far = builtin("tls_far", 1);
  for (const char* method : {"voxel", "normal"}) {
    SCOPED_TRACE(method);
    std::vector<std::uint8_t> cut, plain;
    const gf::FilterStats st = runChecked(method, far, &cut, {{"max_range", "1000"}});
    EXPECT_EQ(st.out_of_range_points, 0u) << st.scan_reason;
    runChecked(method, far, &plain, {{"max_range", "0"}});
    EXPECT_EQ(cut, plain);
    EXPECT_GT(f1(cut, far), 0.97);
  }
}

// ------------------------------------------------------------------- the modes it switches

TEST(ScanType, AutoAllocatesNothingAfterTheFirstScan) {
  // The voxel filter's promise (no allocation once a size was seen) holds with the decision
  // (the airborne surface, MorphGround, makes no such promise).
  const Cloud street = builtin("lidar", 1), verge = builtin("verge", 2);
  for (const Cloud* c : {&street, &verge}) {
    gf::VoxelGroundFilter f;  // scan_type auto
    std::vector<std::uint8_t> first, labels(c->size(), 2);
    gf::FilterStats stats;
    f.filter(c->view(), &first, &stats);
    const std::size_t before = allocationCount().load();
    f.filter(c->view(), &labels, &stats);
    f.filter(c->view(), &labels, nullptr);
    EXPECT_EQ(allocationCount().load() - before, 0u) << stats.scan_type;
    EXPECT_EQ(first, labels);
  }
}

TEST(ScanType, AutoGivesTheForcedModesLabels) {
  for (const char* method : {"voxel", "normal"}) {
    SCOPED_TRACE(method);
    const Cloud street = builtin("lidar", 2), tile = builtin("airborne", 2);
    std::vector<std::uint8_t> a, b;
    gf::FilterStats st = runChecked(method, street, &a);
    EXPECT_EQ(st.scan_type, "ground");
    EXPECT_EQ(st.scan_reason.rfind("auto: ", 0), 0u) << st.scan_reason;
    st = runChecked(method, street, &b, {{"scan_type", "ground"}});
    EXPECT_EQ(st.scan_reason, "scan_type: ground");
    EXPECT_EQ(a, b);  // auto on a ground-level scan: exactly the ground-level labels
    st = runChecked(method, tile, &a);
    EXPECT_EQ(st.scan_type, "airborne");
    runChecked(method, tile, &b, {{"scan_type", "airborne"}});
    EXPECT_EQ(a, b);
    // The airborne mode is the airborne preset's surface (SMRF's values, 0.5 m threshold).
    runChecked(method, tile, &b, {{"morph_ground", "true"}, {"plane_distance", "0.5"}});
    EXPECT_EQ(a, b);
    EXPECT_GT(f1(a, tile), 0.95);
    // Forced the other way, the same scans give different labels: the switch does something.
    runChecked(method, tile, &b, {{"scan_type", "ground"}});
    EXPECT_LT(f1(b, tile), f1(a, tile) - 0.05);
    st = runChecked(method, street, &b, {{"scan_type", "tls"}});
    EXPECT_EQ(st.scan_type, "tls");
  }
}

// Three tripod stations merged in rough terrain: their density peaks near one station, so auto
// reads a single scan with its sensor at the origin (scan type ground, not registered). The
// normal method refused the ground planes of the other stations' terrain that lies above that
// "sensor" (F1 0.91 against 0.98) until it looked from the origin: much lies behind nearer
// points, so no sensor judges the planes, as with scan_type: registered (docs/scan_types.md,
// "Failure modes").
TEST(ScanType, RegisteredSettingTakesTheSensorAway) {
  const Cloud merged = generated(gf::parseSceneSpec("stations:1:layout=offroad,tls_points=60000"));
  std::vector<std::uint8_t> a, b;
  gf::FilterStats st = runChecked("normal", merged, &a);
  EXPECT_EQ(st.scan_type, "ground");
  EXPECT_EQ(st.scan_reason.find("registered"), std::string::npos) << st.scan_reason;
  EXPECT_NE(st.note.find("behind nearer ones seen from the origin"), std::string::npos) << st.note;
  st = runChecked("normal", merged, &b, {{"scan_type", "registered"}});
  EXPECT_EQ(st.scan_type, "ground");
  EXPECT_EQ(st.scan_reason, "scan_type: registered");
  EXPECT_GT(f1(b, merged), 0.95);
  EXPECT_GT(f1(a, merged), f1(b, merged) - 0.005);
  // The same steps as auto takes for a cloud it finds registered (2.4 km from the origin), and
  // max_range does not cut it.
  const Cloud far = builtin("tls_far", 1);
  for (const char* method : {"voxel", "normal"}) {
    SCOPED_TRACE(method);
    runChecked(method, far, &a);
    st = runChecked(method, far, &b, {{"scan_type", "registered"}, {"max_range", "1000"}});
    EXPECT_EQ(st.out_of_range_points, 0u);
    EXPECT_EQ(a, b);
  }
}

TEST(ScanType, MorphGroundStillForcesTheAirborneMode) {
  const Cloud street = builtin("lidar", 1);
  std::vector<std::uint8_t> labels;
  const gf::FilterStats st =
      runChecked("voxel", street, &labels, {{"morph_ground", "true"}, {"scan_type", "ground"}});
  EXPECT_EQ(st.scan_type, "airborne");
  EXPECT_EQ(st.scan_reason, "morph_ground: true");
}

TEST(ScanType, BadSettingIsRefusedByName) {
  try {
    gf::makeGroundFilter("voxel", {{"scan_type", "nadir"}});
    FAIL() << "accepted scan_type nadir";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("scan_type"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nadir"), std::string::npos) << e.what();
  }
  EXPECT_THROW(gf::makeGroundFilter("normal", {{"scan_type", "Auto"}}), std::invalid_argument);
}

// --------------------------------------------------------- max_range and a far airborne tile

TEST(ScanType, MaxRangeDoesNotCutAnAirborneTile) {
  const Cloud tile = builtin("airborne", 1);
  Cloud far = tile;  // the same tile 4.5 km from the origin (UTM minus an offset, say)
  for (std::size_t i = 0; i < far.size(); ++i) {
    far.xyz[3 * i] += 3200.f;
    far.xyz[3 * i + 1] -= 2900.f;
    far.xyz[3 * i + 2] += 1500.f;
  }
  for (const char* method : {"voxel", "normal"}) {
    SCOPED_TRACE(method);
    std::vector<std::uint8_t> near_labels, far_labels;
    runChecked(method, tile, &near_labels);
    const gf::FilterStats st = runChecked(method, far, &far_labels, {{"max_range", "1000"}});
    EXPECT_EQ(st.scan_type, "airborne");
    EXPECT_EQ(st.out_of_range_points, 0u);
    EXPECT_NEAR(f1(far_labels, far), f1(near_labels, tile), 0.002);
    // Forced ground-level, the working volume cuts it as before: every point out of range.
    const gf::FilterStats cut =
        runChecked(method, far, &far_labels, {{"max_range", "1000"}, {"scan_type", "ground"}});
    EXPECT_EQ(cut.out_of_range_points, far.size());
    EXPECT_EQ(std::count(far_labels.begin(), far_labels.end(), 1), 0);
  }
}

TEST(ScanType, MaxRangeStillCutsAGroundLevelScan) {
  Cloud c = builtin("lidar", 1);
  const std::size_t n = c.size();
  c.add(1500.f, 0.f, 0.f, false);  // one far echo
  std::vector<std::uint8_t> labels;
  const gf::FilterStats st = runChecked("voxel", c, &labels, {{"max_range", "1000"}});
  EXPECT_EQ(st.scan_type, "ground");
  EXPECT_EQ(st.out_of_range_points, 1u);
  EXPECT_EQ(labels[n], 0);
}

// ------------------------------------------------------------------------------ bad input

TEST(ScanType, OnePoint) {
  Cloud c;
  c.add(1.f, 2.f, -1.7f, true);
  for (const char* method : {"voxel", "normal"}) {
    std::vector<std::uint8_t> labels;
    const gf::FilterStats st = runChecked(method, c, &labels);
    EXPECT_EQ(st.scan_type, "ground");
    EXPECT_NE(st.scan_reason.find("too few"), std::string::npos) << st.scan_reason;
  }
}

TEST(ScanType, AllPointsAtOneHeight) {
  Cloud grid, flat = builtin("lidar", 1);
  for (int i = 0; i < 200; ++i) {
    for (int j = 0; j < 200; ++j) grid.add(0.5f * i - 50.f, 0.5f * j - 50.f, -1.7f, true);
  }
  for (std::size_t i = 0; i < flat.size(); ++i) flat.xyz[3 * i + 2] = -1.73f;
  for (const char* method : {"voxel", "normal"}) {
    SCOPED_TRACE(method);
    std::vector<std::uint8_t> labels;
    runChecked(method, grid, &labels);
    // Either mode finds a level plane of points ground.
    EXPECT_EQ(std::count(labels.begin(), labels.end(), 1), static_cast<long>(grid.size()));
    const gf::FilterStats st = runChecked(method, flat, &labels);
    EXPECT_EQ(st.scan_type, "ground") << st.scan_reason;  // still a vehicle's density pattern
  }
  // One column of points (no footprint): too small to judge.
  Cloud column;
  for (int i = 0; i < 500; ++i) column.add(3.f, 4.f, -1.7f + 0.001f * i, true);
  EXPECT_NE(classify(column).reason.find("too little"), std::string::npos);
  std::vector<std::uint8_t> labels;
  runChecked("voxel", column, &labels);
}

TEST(ScanType, TwoSensorsMerged) {
  // A vehicle scan and an airborne tile of about as many points over the same place.
  const Cloud street = builtin("lidar", 1);
  gf::SceneParams p = gf::builtinSceneParams("airborne");
  p.scene_extent = 80.0;
  p.airborne_density = 8.0;
  Cloud both = street;
  const Cloud tile = generated(p);
  both.xyz.insert(both.xyz.end(), tile.xyz.begin(), tile.xyz.end());
  both.truth.insert(both.truth.end(), tile.truth.begin(), tile.truth.end());
  for (const char* method : {"voxel", "normal"}) {
    std::vector<std::uint8_t> labels;
    const gf::FilterStats st = runChecked(method, both, &labels);
    EXPECT_NE(st.scan_reason.find("densest tenth"), std::string::npos) << st.scan_reason;
  }
}

TEST(ScanType, SensorOriginFarOutsideTheCloud) {
  const Cloud street = builtin("lidar", 1);
  const float origins[][3] = {{4000.f, 0.f, 0.f}, {0.f, -3000.f, -4000.f}, {0.f, 0.f, 1000.f}};
  for (const auto& o : origins) {
    for (const char* method : {"voxel", "normal"}) {
      SCOPED_TRACE(std::string(method) + " origin " + std::to_string(o[0]) + " " +
                   std::to_string(o[1]) + " " + std::to_string(o[2]));
      auto f = gf::makeGroundFilter(method, {{"max_range", "0"}});
      static_cast<gf::WorkingVolumeFilter&>(*f).setOrigin(o[0], o[1], o[2]);
      std::vector<std::uint8_t> labels;
      gf::FilterStats st;
      f->filter(street.view(), &labels, &st);
      ASSERT_EQ(labels.size(), street.size());
      for (std::uint8_t l : labels) ASSERT_TRUE(l == 0 || l == 1);
      EXPECT_FALSE(st.scan_reason.empty());
    }
  }
  // Beside the cloud or below it, the density pattern still says ground-level (from far below,
  // the points lie high above the origin, which reads as a tripod scanner's: same mode).
  EXPECT_EQ(classify(street, 4000.f, 0.f, 0.f).type, gf::ScanType::kGround);
  EXPECT_NE(classify(street, 0.f, -3000.f, -4000.f).type, gf::ScanType::kAirborne);
}

TEST(ScanType, WallSeenEdgeOnAndACloudInMillimetres) {
  // Every point at one x (a wall seen edge-on: no footprint across), and a registered street
  // given in millimetres: a decision, a reason, every point labelled, no crash.
  Cloud wall;
  for (int i = 0; i < 400; ++i) {
    for (int j = 0; j < 40; ++j) wall.add(5.f, 0.1f * i - 20.f, 0.1f * j, j == 0);
  }
  Cloud mm = builtin("mls", 1);
  for (float& v : mm.xyz) v *= 1000.f;
  for (const Cloud* c : {&wall, &mm}) {
    for (const char* method : {"voxel", "normal"}) {
      std::vector<std::uint8_t> labels;
      runChecked(method, *c, &labels, {{"max_range", "0"}});
    }
  }
  EXPECT_FALSE(classify(wall).reason.empty());
  // Millimetres: rule 4's columns are 1 unit wide, so each holds about one point and the rule
  // does not judge (documented: the filters' lengths are metres too).
  const gf::ScanDecision d = classify(mm);
  EXPECT_NE(d.reason.find("1 m columns"), std::string::npos) << d.reason;
  EXPECT_EQ(d.type, gf::ScanType::kAirborne) << d.reason;
}

TEST(ScanType, HugeCloudIsJudgedFromABoundedRead) {
  // 6 M points (a registered street repeated along x): rule 4 reads at most kMaxRead of them.
  const Cloud street = builtin("mls", 1);
  Cloud big;
  big.xyz.reserve(street.xyz.size() * 10);
  for (int r = 0; r < 10; ++r) {
    for (std::size_t i = 0; i < street.size(); ++i) {
      big.xyz.insert(big.xyz.end(),
                     {street.xyz[3 * i] + 100.f * r, street.xyz[3 * i + 1], street.xyz[3 * i + 2]});
    }
  }
  gf::ScanTypeClassifier k;
  const float o[3] = {0.f, 0.f, 0.f};
  gf::ScanDecision d;
  k.classify(big.view(), o, &d);
  EXPECT_EQ(d.type, gf::ScanType::kGround) << d.reason;
  const gf::ScanMeasures m = k.measure(big.view(), o);
  EXPECT_GT(big.size(), 5000000u);
  EXPECT_LE(m.read, gf::ScanTypeClassifier::kMaxRead);
  EXPECT_GT(m.read, gf::ScanTypeClassifier::kMaxRead / 2);
}

TEST(ScanType, EmptyAndInvalidClouds) {
  Cloud nan;
  for (int i = 0; i < 100; ++i) nan.add(NAN, 0.f, 0.f, false);
  const float o[3] = {0.f, 0.f, 0.f};
  EXPECT_EQ(gf::ScanTypeClassifier().measure(nan.view(), o).hidden_share, 0.0);
  // Points straight above and below the origin (a TLS zenith: x = y = 0, no azimuth) among a
  // ground ring: a defined share (the fuzzer found 0 / 0 there).
  Cloud zenith;
  for (int i = 0; i < 2000; ++i) {
    const float a = 0.0031416f * static_cast<float>(i), r = 3.f + 0.01f * static_cast<float>(i);
    zenith.add(r * std::cos(a), r * std::sin(a), -1.5f, true);
  }
  for (int i = 0; i < 200; ++i) zenith.add(0.f, 0.f, 2.f + 0.1f * static_cast<float>(i % 2), false);
  for (int i = 0; i < 50; ++i) zenith.add(0.f, 0.f, -1.5f - 0.5f * static_cast<float>(i), false);
  const double share = gf::ScanTypeClassifier().measure(zenith.view(), o).hidden_share;
  EXPECT_GE(share, 0.0);
  EXPECT_LE(share, 0.1);
  for (const char* method : {"voxel", "normal"}) {
    std::vector<std::uint8_t> labels;
    runChecked(method, nan, &labels);
    EXPECT_EQ(std::count(labels.begin(), labels.end(), 1), 0);
    runChecked(method, Cloud(), &labels);
  }
}
