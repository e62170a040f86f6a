// A sensor mounted tilted with no gravity frame (level_tilt, src/core/common/ground_tilt.h): the
// tilt of the ground around the sensor, the scan levelled onto it, and the normal method on
// generated scans from tilted mounts (docs/normal_method.md, "A sensor mounted tilted").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/ground_tilt.h"
#include "eval/metrics.h"
#include "eval/scene_generator.h"
#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/normal_ground_filter.h"
#include "ground_filter/voxel_ground_filter.h"
#include "knn/kdtree_neighbor_search.h"
#include "normal/filter_executor.h"
#include "normal/order.h"

namespace gf = ground_filter;

namespace {

// The filters' default level_tilt [deg]: a near plane leaning this much is checked further.
constexpr double kLevelTilt = 5.0;

// F1 of `labels` against `truth` (ground positive).
double f1Of(const std::vector<std::uint8_t>& labels, const std::vector<std::uint8_t>& truth) {
  const std::vector<std::int8_t> t(truth.begin(), truth.end());
  return gf::computeMetrics(gf::countConfusion(labels, t)).f1;
}

double pct(std::vector<float> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * (v.size() - 1))];
}

// The road's z after level() (the road of these scenes is flat: slope_x = slope_y = 0).
std::vector<float> roadHeights(const gf::GeneratedScan& scan, const std::vector<float>& xyz) {
  std::vector<float> z;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (scan.semantic[i] == gf::kClassRoad && std::isfinite(xyz[3 * i + 2])) {
      z.push_back(xyz[3 * i + 2]);
    }
  }
  return z;
}

}  // namespace

// The plane through the lowest point of each column around the sensor is the road's, to a
// fraction of a degree, whatever the mount's roll and pitch; level() turns the road flat.
TEST(GroundTilt, FindsTheMountsTiltAndLevelsTheRoad) {
  const float origin[3] = {0.f, 0.f, 0.f};
  // Up to a handheld rig's 45 deg and beyond (40 / 40: 54 deg; 58 deg, near kMaxTilt's 60);
  // kMaxTilt 35 found no plane from 45 deg on.
  const double pitch_roll[][2] = {{0.0, 0.0},  {10.0, 0.0},  {-12.0, 6.0}, {20.0, -15.0},
                                  {45.0, 0.0}, {40.0, 40.0}, {0.0, -58.0}};
  double level_spread = 0.0;  // of the level mount (the first)
  for (const auto& pr : pitch_roll) {
    gf::SceneParams p = gf::builtinSceneParams("lidar");
    p.slope_x = p.slope_y = 0.0;
    p.mount_pitch_deg = pr[0];
    p.mount_roll_deg = pr[1];
    const gf::GeneratedScan scan = gf::generateScene(p);
    const gf::CloudView view = gf::CloudView::packedXyz(scan.xyz.data(), scan.size());
    gf::GroundTiltEstimator estimator;
    const gf::GroundTilt tilt = estimator.estimate(view, origin, kLevelTilt);
    ASSERT_TRUE(tilt.found) << pr[0] << " " << pr[1];
    const double expected =
        std::acos(std::cos(pr[0] * M_PI / 180.0) * std::cos(pr[1] * M_PI / 180.0)) * 180.0 / M_PI;
    EXPECT_NEAR(tilt.tilt_deg, expected, 0.5) << pr[0] << " " << pr[1];
    EXPECT_GE(tilt.inliers, gf::GroundTiltEstimator::kMinInliers);
    std::vector<float> xyz;
    gf::GroundTiltEstimator::level(view, origin, tilt, &xyz);
    const std::vector<float> before = roadHeights(scan, scan.xyz), after = roadHeights(scan, xyz);
    // The road (its ramp included) back where the level mount sees it, to a few cm.
    const double spread = pct(after, 0.95) - pct(after, 0.05);
    if (pr[0] == 0.0 && pr[1] == 0.0) level_spread = spread;
    EXPECT_NEAR(pct(after, 0.5), -1.73, 0.05) << pr[0] << " " << pr[1];
    EXPECT_NEAR(spread, level_spread, 0.03) << pr[0] << " " << pr[1];
    if (expected > 5.0) EXPECT_GT(pct(before, 0.95) - pct(before, 0.05), level_spread + 1.0);
  }
}

// A mount leaning more than kMaxTilt (a sensor nearly on its side) is left to gravity_frame:
// turned 70 deg, a street scan's walls lean 20 deg and its road 70 deg from the frame's z; a
// wall must never be taken for the ground to turn onto. Not turned (kMaxTilt 60), or turned
// onto the road itself (a larger limit: 75 turns it by 68.8 deg).
TEST(GroundTilt, AMountBeyondTheLimitIsNotTurnedOntoAWall) {
  const float origin[3] = {0.f, 0.f, 0.f};
  const gf::GeneratedScan scan =
      gf::generateScene(gf::parseSceneSpec("lidar:1:mount_pitch_deg=-70"));
  gf::GroundTiltEstimator estimator;
  const gf::GroundTilt t = estimator.estimate(
      gf::CloudView::packedXyz(scan.xyz.data(), scan.size()), origin, kLevelTilt);
  if (t.turns(5.0)) EXPECT_NEAR(t.tilt_deg, 70.0, 2.0) << t.inliers << " of " << t.columns;
  EXPECT_EQ(t.turns(5.0), 70.0 <= gf::GroundTiltEstimator::kMaxTilt) << t.tilt_deg << " deg";
}

// No ground plane where none lies below the sensor: a ceiling 0.8 m above it on a parking level
// is not the ground (the floor is), and a cloud with nothing near the sensor gives none.
TEST(GroundTilt, CeilingsAndEmptySurroundingsGiveNoTilt) {
  const float origin[3] = {0.f, 0.f, 0.f};
  const gf::GeneratedScan garage = gf::generateScene(gf::parseSceneSpec("garage:1"));
  gf::GroundTiltEstimator estimator;
  const gf::GroundTilt t = estimator.estimate(
      gf::CloudView::packedXyz(garage.xyz.data(), garage.size()), origin, kLevelTilt);
  ASSERT_TRUE(t.found);
  EXPECT_LT(t.tilt_deg, 1.0);
  std::vector<float> far;  // a wall 40 m away, nothing within 15 m
  for (int i = 0; i < 2000; ++i) {
    far.insert(far.end(),
               {40.f, static_cast<float>(i % 50) * 0.2f, static_cast<float>(i / 50) * 0.1f});
  }
  EXPECT_FALSE(
      estimator.estimate(gf::CloudView::packedXyz(far.data(), 2000), origin, kLevelTilt).found);
}

// A sensor on a mast, 7 m up: the lowest points within 15 m are where its lowest beam meets
// walls, cars and crowns, on that beam's cone; the best plane through them leant 8.7 deg, the
// scan was turned onto it and lost its ground (voxel F1 0.98 -> 0.68, normal 0.95 -> 0.86). A
// sensor more than kMaxHeight above that plane reads its lean from the ground 15-40 m out: the
// level mast is not turned, the same mast pitched 20 deg down is; on a car (1.73 m) the near
// plane stands.
TEST(GroundTilt, ASensorOnAMastIsNotTurnedOntoItsLowestBeam) {
  const float origin[3] = {0.f, 0.f, 0.f};
  gf::GroundTiltEstimator estimator;
  const gf::GeneratedScan mast = gf::generateScene(gf::parseSceneSpec("lidar:6:sensor_height=7"));
  const gf::GroundTilt high = estimator.estimate(
      gf::CloudView::packedXyz(mast.xyz.data(), mast.size()), origin, kLevelTilt);
  EXPECT_TRUE(high.high);
  EXPECT_GT(high.height, gf::GroundTiltEstimator::kMaxHeight);
  EXPECT_FALSE(high.turns(5.0)) << high.tilt_deg << " deg, " << high.height << " m";
  // Pitched 20 deg down, the ground farther out leans by the pitch as well: turned by it.
  const gf::GeneratedScan pitched =
      gf::generateScene(gf::parseSceneSpec("lidar:6:sensor_height=6,mount_pitch_deg=20"));
  const gf::GroundTilt down = estimator.estimate(
      gf::CloudView::packedXyz(pitched.xyz.data(), pitched.size()), origin, kLevelTilt);
  EXPECT_TRUE(down.high);
  EXPECT_TRUE(down.turns(5.0));
  EXPECT_NEAR(down.tilt_deg, 21.0, 1.5);  // the pitch and the street's 2 % rise
  const gf::GeneratedScan car = gf::generateScene(gf::parseSceneSpec("lidar:6"));
  const gf::GroundTilt low =
      estimator.estimate(gf::CloudView::packedXyz(car.xyz.data(), car.size()), origin, kLevelTilt);
  ASSERT_TRUE(low.found);
  EXPECT_FALSE(low.high);
  EXPECT_NEAR(low.height, 1.73, 0.2);
  EXPECT_LT(low.tilt_deg, 3.0);
  for (const char* method : {"voxel", "normal"}) {
    SCOPED_TRACE(method);
    gf::ParamSettings settings;
    if (std::string(method) == "normal") settings.push_back({"threads", "2"});
    auto filter = gf::makeGroundFilter(method, settings);
    std::vector<std::uint8_t> labels;
    filter->filter(gf::CloudView::packedXyz(mast.xyz.data(), mast.size()), &labels, nullptr);
    EXPECT_GT(f1Of(labels, mast.truth), 0.93);
  }
}

// A 32-beam sensor 3 m up with a narrow vertical field (-10 to +3.3 deg: a long-range sensor on
// a truck's roof) meets the ground only 17 m out: the lowest points within 15 m lie on car roofs,
// crowns and walls 0.15-0.9 m below it, and the best plane through them leant 6.7-9.6 deg. The
// scan was turned onto it and lost its ground (voxel F1 0.76 on lidar:1, 0.78 on lidar:3). Where
// the ring 15-40 m out gives a level plane more than kBelowNear lower, that plane decides: the
// level mount is not turned.
TEST(GroundTilt, ANarrowSensorHighUpIsNotTurnedOntoObjectTops) {
  const float origin[3] = {0.f, 0.f, 0.f};
  const std::string narrow =
      ":sensor_height=3,beams=32,vertical_min_deg=-10,vertical_max_deg=3.3,uniform_beams=1,"
      "azimuth_steps=1800";
  gf::GroundTiltEstimator estimator;
  for (const char* seed : {"lidar:1", "lidar:3"}) {
    SCOPED_TRACE(seed);
    const gf::GeneratedScan scan = gf::generateScene(gf::parseSceneSpec(seed + narrow));
    const gf::CloudView view = gf::CloudView::packedXyz(scan.xyz.data(), scan.size());
    const gf::GroundTilt t = estimator.estimate(view, origin, kLevelTilt);
    EXPECT_FALSE(t.turns(kLevelTilt)) << t.tilt_deg << " deg, " << t.height << " m";
    auto filter = gf::makeGroundFilter("voxel", {});
    std::vector<std::uint8_t> labels;
    filter->filter(view, &labels, nullptr);
    EXPECT_GT(f1Of(labels, scan.truth), 0.9);
  }
}

// A sensor pitched 15 deg down with no gravity frame: the ground's normals lean out of the
// candidate window (75-105 deg from horizontal) and the normal method found no ground at all
// (F1 0.0 on the street; rolled 12 deg over the trail 0.70). Levelled onto the ground around
// the sensor first, it keeps what it has on a level mount; with level_tilt 0 the loss is back.
// A level mount is not turned.
TEST(NormalGroundFilter, LevelsTheScanOfATiltedMount) {
  const char* specs[][2] = {{"lidar:1:mount_pitch_deg=15", "lidar:1"},
                            {"trail:1:mount_roll_deg=12", "trail:1"},
                            {"verge:1:mount_pitch_deg=-8,mount_roll_deg=6", "verge:1"},
                            {"offroad:1:mount_pitch_deg=45", "offroad:1"}};
  for (const auto& s : specs) {
    const gf::GeneratedScan tilted = gf::generateScene(gf::parseSceneSpec(s[0]));
    const gf::GeneratedScan level = gf::generateScene(gf::parseSceneSpec(s[1]));
    gf::NormalGroundFilterParams p;
    p.threads = 2;
    gf::NormalGroundFilter filter(p);
    std::vector<std::uint8_t> labels;
    gf::FilterStats stats;
    filter.filter(gf::CloudView::packedXyz(level.xyz.data(), level.size()), &labels, &stats);
    const double f1_level = f1Of(labels, level.truth);
    EXPECT_EQ(stats.note.find("turned"), std::string::npos) << s[1] << ": " << stats.note;
    filter.filter(gf::CloudView::packedXyz(tilted.xyz.data(), tilted.size()), &labels, &stats);
    EXPECT_GT(f1Of(labels, tilted.truth), f1_level - 0.02) << s[0];
    EXPECT_NE(stats.note.find("turned onto it"), std::string::npos) << s[0] << ": " << stats.note;
  }
  const gf::GeneratedScan street = gf::generateScene(gf::parseSceneSpec(specs[0][0]));
  gf::NormalGroundFilterParams off;
  off.threads = 2;
  off.level_tilt = 0.0;
  std::vector<std::uint8_t> labels;
  gf::NormalGroundFilter(off).filter(gf::CloudView::packedXyz(street.xyz.data(), street.size()),
                                     &labels);
  EXPECT_LT(f1Of(labels, street.truth), 0.5);
}

// The voxel method levels the same way (its flat-voxel test leans with the ground): each tilted
// scene within 0.01 of its level mount's F1, a level mount not turned, and without the rule the
// street pitched 20 deg more than 0.01 lower (94.9 against 96.8 %).
TEST(VoxelGroundFilter, LevelsTheScanOfATiltedMount) {
  const char* specs[][2] = {{"lidar:1:mount_pitch_deg=20", "lidar:1"},
                            {"trail:1:mount_roll_deg=20", "trail:1"},
                            {"verge:1:mount_pitch_deg=-8,mount_roll_deg=6", "verge:1"},
                            {"lidar:1:mount_pitch_deg=40,mount_roll_deg=40", "lidar:1"}};
  gf::VoxelGroundFilterParams p;
  gf::VoxelGroundFilter filter(p);
  gf::VoxelGroundFilterParams off = p;
  off.level_tilt = 0.0;
  gf::VoxelGroundFilter unlevelled(off);
  for (const auto& s : specs) {
    const gf::GeneratedScan tilted = gf::generateScene(gf::parseSceneSpec(s[0]));
    const gf::GeneratedScan level = gf::generateScene(gf::parseSceneSpec(s[1]));
    std::vector<std::uint8_t> labels;
    gf::FilterStats stats;
    filter.filter(gf::CloudView::packedXyz(level.xyz.data(), level.size()), &labels, &stats);
    const double f1_level = f1Of(labels, level.truth);
    EXPECT_EQ(stats.note.find("turned"), std::string::npos) << s[1] << ": " << stats.note;
    const gf::CloudView view = gf::CloudView::packedXyz(tilted.xyz.data(), tilted.size());
    filter.filter(view, &labels, &stats);
    EXPECT_GT(f1Of(labels, tilted.truth), f1_level - 0.01) << s[0];
    EXPECT_NE(stats.note.find("turned onto it"), std::string::npos) << s[0] << ": " << stats.note;
    if (s == specs[0]) {
      unlevelled.filter(view, &labels, &stats);
      EXPECT_LT(f1Of(labels, tilted.truth), f1_level - 0.01) << s[0];
    }
  }
}

namespace {

// An executor that runs the CPU stages on what it is given (the levelling off: the filter levels
// before it), counting its calls and keeping the first point of each cloud it saw.
class CpuExecutor : public gf::NormalFilterExecutor {
 public:
  /// `keeps_order`: lastColumnOrder() gives the scan's column order, as the GPU's does.
  explicit CpuExecutor(std::vector<float>* firsts, bool keeps_order = false)
      : firsts_(firsts), keeps_order_(keeps_order) {}
  std::string name() const override { return "cpu-executor"; }
  bool run(const gf::CloudView& cloud, int sample_stride, const double* /*sensor*/,
           std::vector<std::uint8_t>* labels, gf::FilterStats* stats) override {
    firsts_->insert(firsts_->end(), {cloud.x(0), cloud.y(0), cloud.z(0)});
    last_ = cloud;
    gf::NormalGroundFilterParams p;
    p.threads = 2;
    p.scan_type = "ground";
    p.level_tilt = 0.0;
    p.max_line_ratio = 0.0;  // the stride as given
    p.sample_stride = sample_stride;
    gf::NormalGroundFilter inner(p);
    gf::FilterStats own;
    inner.filter(cloud, labels, &own);
    stats->ground_points = own.ground_points;
    stats->invalid_points = own.invalid_points;
    stats->backend = name();
    stats->stage_ms.emplace_back("executor", own.total_ms);
    return true;
  }
  std::string lastNote() const override { return ""; }
  bool lastColumnOrder(std::vector<std::uint32_t>* source) override {
    if (!keeps_order_) return false;
    gf::normal::OrderStage order;
    gf::normal::OrderedPoints ordered;
    order.run(last_, gf::NormalGroundFilterParams().cell_size, false, 0, 1, &ordered);
    *source = ordered.source;
    return true;
  }

 private:
  std::vector<float>* firsts_;
  bool keeps_order_;
  gf::CloudView last_;
};

std::size_t stagesNamed(const gf::FilterStats& st, const std::string& name) {
  return static_cast<std::size_t>(std::count_if(st.stage_ms.begin(), st.stage_ms.end(),
                                                [&](const auto& s) { return s.first == name; }));
}

}  // namespace

// With an executor (the GPU) the tilt check runs beside it on the scan as it comes: a level
// mount's scan runs once, a tilted one's run is dropped and the turned scan runs again; either
// way the labels, the note and the stage list are those of the CPU stages, which level first.
TEST(NormalGroundFilter, TiltCheckBesideTheExecutorGivesTheCpuLabels) {
  for (const char* spec : {"lidar:1", "lidar:1:mount_pitch_deg=15", "trail:1:mount_roll_deg=12"}) {
    const gf::GeneratedScan s = gf::generateScene(gf::parseSceneSpec(spec));
    const gf::CloudView cloud = gf::CloudView::packedXyz(s.xyz.data(), s.size());
    gf::NormalGroundFilterParams p;
    p.threads = 2;
    p.scan_type = "ground";
    std::vector<std::uint8_t> cpu, beside;
    gf::FilterStats cpu_st, st;
    gf::NormalGroundFilter(p).filter(cloud, &cpu, &cpu_st);
    std::vector<float> firsts;
    gf::NormalGroundFilter filter(p, std::make_unique<gf::KdTreeNeighborSearch>(2),
                                  std::make_unique<CpuExecutor>(&firsts));
    for (int rep = 0; rep < 2; ++rep) {  // the second scan: the scan lines kept from the first
      firsts.clear();
      filter.filter(cloud, &beside, &st);
      const bool turned = cpu_st.note.find("turned onto it") != std::string::npos;
      EXPECT_EQ(turned, std::string(spec) != "lidar:1") << spec << ": " << cpu_st.note;
      ASSERT_EQ(firsts.size(), turned ? 6u : 3u) << spec;
      EXPECT_EQ(firsts[0], s.xyz[0]) << spec;              // the scan as it comes first
      if (turned) EXPECT_NE(firsts[5], s.xyz[2]) << spec;  // then the turned one
      EXPECT_EQ(beside, cpu) << spec;
      EXPECT_EQ(st.backend, "cpu-executor") << spec;
      EXPECT_EQ(st.note, cpu_st.note) << spec;
      EXPECT_EQ(st.ground_points, cpu_st.ground_points) << spec;
      EXPECT_EQ(stagesNamed(st, "level"), 1u) << spec;
      EXPECT_EQ(stagesNamed(st, "executor"), 1u) << spec;
      EXPECT_EQ(stagesNamed(st, "lines"), 1u) << spec;
    }
  }
}

// A sparse sensor's scan through an executor (the GPU): the lowest scan line on a wall (step 7)
// runs on the host after it, on the executor's column order where it keeps one (the GPU's,
// downloaded) or on the host's own: the CPU's labels either way.
TEST(NormalGroundFilter, LowestLinesAfterTheExecutorGiveTheCpuLabels) {
  for (const char* spec : {"lidar16:1", "lidar16:2"}) {
    const gf::GeneratedScan s = gf::generateScene(gf::parseSceneSpec(spec));
    const gf::CloudView cloud = gf::CloudView::packedXyz(s.xyz.data(), s.size());
    gf::NormalGroundFilterParams p;
    p.threads = 2;
    p.scan_type = "ground";
    std::vector<std::uint8_t> cpu;
    gf::FilterStats cpu_st;
    gf::NormalGroundFilter(p).filter(cloud, &cpu, &cpu_st);
    ASSERT_EQ(stagesNamed(cpu_st, "line_walls"), 1u) << spec;
    for (const bool keeps : {false, true}) {
      std::vector<float> firsts;
      gf::NormalGroundFilter filter(p, std::make_unique<gf::KdTreeNeighborSearch>(2),
                                    std::make_unique<CpuExecutor>(&firsts, keeps));
      std::vector<std::uint8_t> labels;
      gf::FilterStats st;
      filter.filter(cloud, &labels, &st);
      EXPECT_EQ(st.backend, "cpu-executor") << spec;
      EXPECT_EQ(stagesNamed(st, "line_walls"), 1u) << spec;
      EXPECT_EQ(labels, cpu) << spec << (keeps ? ", its order" : ", the host's order");
      EXPECT_EQ(st.ground_points, cpu_st.ground_points) << spec;
    }
  }
}
