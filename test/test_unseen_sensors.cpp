// Sensors the dev data does not have (generated scenes with exact truth, the scenes of
// scripts/sensor_sweep.py): each failure mode seen on one of them, kept from coming back; and
// returns mirrored under the ground (docs/tuning.md, scripts/derive_scans.py --mirror).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/densest_centre.h"
#include "eval/metrics.h"
#include "eval/scene_generator.h"
#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"

namespace ground_filter {
namespace {

struct Score {
  double f1 = 0.0;
  double road_recall = 0.0;      // share of the road's points labelled ground
  std::size_t crown_ground = 0;  // vegetation points labelled ground
  double upright_ground = 0.0;   // share of the car and building points labelled ground
};

// `method` on the scene `spec`; its stats into `stats` where given.
Score run(const std::string& method, const std::string& spec, FilterStats* stats = nullptr) {
  const GeneratedScan scan = generateScene(parseSceneSpec(spec));
  const CloudView view = CloudView::packedXyz(scan.xyz.data(), scan.size());
  std::vector<std::uint8_t> labels;
  makeGroundFilter(method)->filter(view, &labels, stats);
  const std::vector<std::int8_t> truth(scan.truth.begin(), scan.truth.end());
  Score s;
  s.f1 = computeMetrics(countConfusion(labels, truth)).f1;
  std::size_t road = 0, road_ground = 0;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (scan.semantic[i] != kClassRoad) continue;
    ++road;
    road_ground += labels[i] == 1;
  }
  std::size_t upright = 0, upright_ground = 0;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    s.crown_ground += scan.semantic[i] == kClassVegetation && labels[i] == 1;
    const bool up = scan.semantic[i] == kClassCar || scan.semantic[i] == kClassBuilding;
    upright += up;
    upright_ground += up && labels[i] == 1;
  }
  s.upright_ground = upright ? static_cast<double>(upright_ground) / upright : 0.0;
  s.road_recall = road ? static_cast<double>(road_ground) / road : 0.0;
  return s;
}

// Points far beyond any sensor's range (a driver's garbage, 2.7e21 m out) join no cell of the
// densest-area search: its keys would overflow, and with the old conversion these 2,000 moved
// the centre off the disc on all three axes (checked).
TEST(UnseenSensors, DensestCentreLeavesOutPointsBeyondItsCells) {
  std::vector<float> xyz;
  for (int r = 1; r <= 40; ++r) {  // a disc of 20 m around (30, -12), ground at -1.7 m
    for (int a = 0; a < 120; ++a) {
      const double ang = a * 2.0 * M_PI / 120.0, rad = 0.5 * r;
      xyz.insert(xyz.end(), {static_cast<float>(30.0 + rad * std::cos(ang)),
                             static_cast<float>(-12.0 + rad * std::sin(ang)), -1.7f});
    }
  }
  DensestCentre finder;
  float plain[3], with_far[3];
  ASSERT_TRUE(finder.find(CloudView::packedXyz(xyz.data(), xyz.size() / 3), plain));
  std::vector<float> far_only;
  for (int i = 0; i < 4000; ++i) {
    const float far = i % 2 ? 2.7e21f : -3.0e38f;
    far_only.insert(far_only.end(), {far, i % 3 ? far : 5.f, 1.f});
    if (i % 2 == 0) xyz.insert(xyz.end(), {far, 5.f, 1.f});
  }
  ASSERT_TRUE(finder.find(CloudView::packedXyz(xyz.data(), xyz.size() / 3), with_far));
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(with_far[d], plain[d], 1e-3) << "axis " << d;
  EXPECT_NEAR(plain[0], 30.0, 2.0);
  EXPECT_NEAR(plain[2], -1.7, 1e-3);
  float none[3];
  EXPECT_FALSE(finder.find(CloudView::packedXyz(far_only.data(), far_only.size() / 3), none));
}

// 32 rings 0.97 deg apart, 3,600 firings, 1.8 m above the street: each ring of the road falls
// into a segment of its own, and the underside of a tree crown (upward beams) became the
// largest flat segment; the voxel method grew its ground model from there (F1 15 %, 12 % of
// the road). The start segment must pass below the sensor.
TEST(UnseenSensors, VoxelGroundGrowsFromBelowTheSensorWhenRingsFallApart) {
  const Score s = run("voxel", "lidar16:1:beams=32,azimuth_steps=3600,sensor_height=1.8");
  EXPECT_GT(s.f1, 0.85);
  EXPECT_GT(s.road_recall, 0.85);
}

// Every sensor of the sweep 1.8 m above the street (the solid-state one with 10 k rays a
// frame), both methods: a method that loses the
// ground on one of them (the normal method on a VLP-16 before the sparse-lines rules: F1 0.5;
// the voxel method above: 0.15) falls far below this.
TEST(UnseenSensors, BothMethodsKeepTheGroundOfEverySensorOfTheSweep) {
  const char* sensors[] = {
      "lidar16:1:beams=16,vertical_min_deg=-15,vertical_max_deg=15,azimuth_steps=1800",
      "lidar16:1:beams=32,vertical_min_deg=-15,vertical_max_deg=15,azimuth_steps=3600",
      "lidar16:1:beams=32,vertical_min_deg=-30.67,vertical_max_deg=10.67,azimuth_steps=2170",
      "lidar16:1:beams=16,vertical_min_deg=-15,vertical_max_deg=15,azimuth_steps=900",
      "lidar16:1:beams=64,vertical_min_deg=-16.6,vertical_max_deg=16.6,azimuth_steps=2048",
      "lidar16:1:beams=128,vertical_min_deg=-22.5,vertical_max_deg=22.5,azimuth_steps=2048",
      "rosette:1:rosette_rays=10000",  // solid-state, a sparse frame
  };
  for (const char* sensor : sensors) {
    const std::string spec = std::string(sensor) + ",sensor_height=1.8";
    for (const char* method : {"voxel", "normal"}) {
      const Score s = run(method, spec);
      EXPECT_GT(s.f1, 0.85) << method << " " << spec;
      EXPECT_GT(s.road_recall, 0.85) << method << " " << spec;
    }
  }
}

// A car in the next lane 3-3.6 m beside the sensor (builtin:lidar:SEED:beside_car=D): the
// blind zone and the car's own shadow leave its bonnet and roof most of their 4 m tile, and the
// normal method's tile plane took them for the ground (F1 0.928 / 0.950 / 0.931 here; 16-17 %
// of the car points within 8 m ground, its roof 1.3-1.5 m up). A tile plane more than 0.75 m
// above its neighbours' is replaced by theirs (normal::raisedTileMedian()); both methods keep
// the near car points off the ground but for its lowest edge (5 % of them).
TEST(UnseenSensors, ACarInTheNextLaneIsNotGround) {
  for (const char* spec :
       {"lidar:1:beside_car=3.6", "lidar:2:beside_car=3.6", "lidar:1:beside_car=3"}) {
    const GeneratedScan scan = generateScene(parseSceneSpec(spec));
    const CloudView view = CloudView::packedXyz(scan.xyz.data(), scan.size());
    const std::vector<std::int8_t> truth(scan.truth.begin(), scan.truth.end());
    for (const char* method : {"voxel", "normal"}) {
      std::vector<std::uint8_t> labels;
      makeGroundFilter(method)->filter(view, &labels, nullptr);
      std::size_t car = 0, car_ground = 0;
      for (std::size_t i = 0; i < scan.size(); ++i) {
        const float* p = &scan.xyz[3 * i];
        if (scan.semantic[i] != kClassCar || p[0] * p[0] + p[1] * p[1] > 64.f) continue;
        ++car;
        car_ground += labels[i] == 1;
      }
      const double f1 = computeMetrics(countConfusion(labels, truth)).f1;
      std::printf("%s %s: F1 %.4f, car points within 8 m %zu of %zu ground\n", method, spec, f1,
                  car_ground, car);
      EXPECT_GT(f1, 0.955) << method << " " << spec;
      ASSERT_GT(car, 10000u) << spec;
      EXPECT_LT(car_ground, car * 8 / 100) << method << " " << spec;
    }
  }
}

// Both methods on a generated indoor scene: F1 above `min_f1`, and fewer than 1 / `share` of
// the building points above `ceiling_z` (the ceiling, tops of walls and pillars) ground.
void expectCeilingOffTheGround(const char* spec, float ceiling_z, double min_f1,
                               std::size_t share) {
  const GeneratedScan scan = generateScene(parseSceneSpec(spec));
  const CloudView view = CloudView::packedXyz(scan.xyz.data(), scan.size());
  const std::vector<std::int8_t> truth(scan.truth.begin(), scan.truth.end());
  for (const char* method : {"voxel", "normal"}) {
    std::vector<std::uint8_t> labels;
    FilterStats stats;
    makeGroundFilter(method)->filter(view, &labels, &stats);
    std::size_t ceiling = 0, ceiling_ground = 0;
    for (std::size_t i = 0; i < scan.size(); ++i) {
      if (scan.semantic[i] != kClassBuilding || !(scan.xyz[3 * i + 2] > ceiling_z)) continue;
      ++ceiling;
      ceiling_ground += labels[i] == 1;
    }
    const double f1 = computeMetrics(countConfusion(labels, truth)).f1;
    std::printf("%s %s (%s): F1 %.4f, ceiling %zu of %zu ground\n", method, spec,
                stats.scan_type.c_str(), f1, ceiling_ground, ceiling);
    EXPECT_GT(f1, min_f1) << method << " " << spec;
    ASSERT_GT(ceiling, 1000u) << spec;
    EXPECT_LT(ceiling_ground, ceiling / share)
        << method << " " << spec << ": " << ceiling_ground << " of " << ceiling << " ground";
  }
}

// A parking level (builtin:garage: OS1-128 1.8 m up, the ceiling 0.8 m above it; a tripod
// scanner; a solid-state sensor): the ceiling is a larger, denser flat surface than the floor
// the sensor sees, and the normal method's tile planes took it for the ground (F1 0.51, 0.64,
// 0.68; 50-75 % of the ceiling ground). No ground plane may pass above the sensor; the ceiling
// stays non-ground (at most 3 %: where a tile's points lie along a few scan lines, as a
// solid-state sensor's petals do, its refit is not judged, docs/normal_method.md).
TEST(UnseenSensors, ACeilingAboveTheSensorIsNotTheGround) {
  for (const char* spec : {"garage:1", "garage:2", "tls:1:layout=garage,tls_points=300000",
                           "rosette:1:layout=garage"}) {
    expectCeilingOffTheGround(spec, 0.5f, 0.9, 33);  // sensor frame: above the sensor's height
  }
}

// A registered indoor cloud (tripod stations merged in a world frame) has no sensor at its
// origin to judge planes by, and its ceiling is as flat as its floor: the normal method took it
// (F1 0.84 and 0.61 here, the second under a 4 m ceiling). A voted point 1 m or more over another
// voted point of its 0.5 m column is left out of the planes (normal::overheadPoint()); the ceiling
// stays non-ground but where no floor is seen under it (3-7 % of it here, at most a tenth). Outdoor
// registered clouds keep their labels within 0.1 F1 (docs/normal_method.md, "Ceilings").
TEST(UnseenSensors, ARegisteredIndoorCloudKeepsItsCeilingOffTheGround) {
  for (const char* spec : {"stations:1:layout=garage,tls_points=300000",
                           "stations:2:layout=garage,tls_points=300000,ceiling_height=4"}) {
    expectCeilingOffTheGround(spec, 2.0f, 0.95, 10);  // world frame: the floor at 0
  }
}

// Tripod stations or sweeps merged in rough terrain, the world frame's origin at the first
// station: scan_type auto reads one scan with its sensor there (the density peaks around it),
// and the normal method's rule that no ground plane passes above the sensor refused the terrain
// higher than that station (F1 0.913 and 0.866 here). Seen from the origin, a tenth to a
// quarter of their points lie behind nearer ones, which a single scan's do not (under 4 %):
// their planes are judged as a registered cloud's (normal/origin_view.h). Single scans keep
// the sensor rule (a ceiling stays off the ground, above).
TEST(UnseenSensors, MergedCloudsInRoughTerrainKeepTheirHigherGround) {
  const std::string kNote = "behind nearer ones seen from the origin";
  for (const auto& c : {std::make_pair("stations:1:layout=offroad", 0.96),
                        std::make_pair("mls:1:layout=offroad", 0.93)}) {
    FilterStats stats;
    EXPECT_GT(run("normal", c.first, &stats).f1, c.second) << c.first;
    EXPECT_NE(stats.note.find(kNote), std::string::npos) << c.first << ": " << stats.note;
  }
  for (const char* spec : {"offroad:1", "trail:2", "garage:1", "rosette:1:layout=garage"}) {
    FilterStats stats;
    run("normal", spec, &stats);
    EXPECT_EQ(stats.note.find(kNote), std::string::npos) << spec << ": " << stats.note;
  }
}

// The other way round: a single scan under a 4 m ceiling, whose ceiling spreads its points as
// evenly as a map's, reads as registered by its side view (scan_type auto, rule 4), and without
// a sensor the ceiling kept its tile planes (F1 0.84, 0.85). Seen from the origin, only 1 % of
// its points lie behind nearer ones: one scan, whose planes the sensor judges (0.97, as with
// scan_type: ground).
TEST(UnseenSensors, ASingleScanReadAsRegisteredKeepsItsSensor) {
  for (const char* spec : {"garage:1:ceiling_height=4", "garage:2:ceiling_height=4"}) {
    FilterStats stats;
    const double f1 = run("normal", spec, &stats).f1;
    EXPECT_NE(stats.scan_reason.find("side view"), std::string::npos) << stats.scan_reason;
    EXPECT_GT(f1, 0.95) << spec;
    EXPECT_NE(stats.note.find("judged with a sensor there"), std::string::npos)
        << spec << ": " << stats.note;
  }
}

// Returns mirrored under the ground (wet asphalt, glass): 3 % of the scan's points, copies of
// points more than 0.5 m above the terrain below them, mirrored in it. A filter that seeds its
// ground from the lowest points (Patchwork++ loses 13 points of F1 on KITTI so,
// docs/tuning.md) moves its ground down; neither method may: the scan's own labels keep their
// F1 and the reflections come out non-ground.
TEST(UnseenSensors, ReflectionsUnderTheGroundChangeNothing) {
  const SceneParams params = parseSceneSpec("lidar:1");
  const GeneratedScan scan = generateScene(params);
  std::vector<float> xyz = scan.xyz;
  std::vector<std::int8_t> truth(scan.truth.begin(), scan.truth.end());
  const std::size_t n = scan.size(), extra = n * 3 / 100;
  std::size_t added = 0;
  for (std::size_t i = 0; i < n && added < extra; i += 7) {  // spread over the scan
    const float* p = &scan.xyz[3 * i];
    const double ground = sceneGroundHeight(params, p[0], p[1]);
    if (p[2] - ground < 0.5) continue;
    xyz.insert(xyz.end(), {p[0], p[1], static_cast<float>(2.0 * ground - p[2])});
    truth.push_back(kTruthIgnored);
    ++added;
  }
  ASSERT_GT(added, extra / 2);
  const std::vector<std::int8_t> own(scan.truth.begin(), scan.truth.end());
  for (const char* method : {"voxel", "normal"}) {
    std::vector<std::uint8_t> clean, mirrored;
    makeGroundFilter(method)->filter(CloudView::packedXyz(scan.xyz.data(), n), &clean);
    makeGroundFilter(method)->filter(CloudView::packedXyz(xyz.data(), n + added), &mirrored);
    const double f1_clean = computeMetrics(countConfusion(clean, own)).f1;
    const double f1_mirrored = computeMetrics(countConfusion(mirrored, truth)).f1;
    EXPECT_GT(f1_clean, 0.9) << method;
    EXPECT_GT(f1_mirrored, f1_clean - 0.01) << method;
    std::size_t reflections_ground = 0;
    for (std::size_t i = n; i < n + added; ++i) reflections_ground += mirrored[i] == 1;
    EXPECT_LT(reflections_ground, added / 10) << method << ": " << reflections_ground << " of "
                                              << added << " reflections labelled ground";
  }
}

// A dual-return sensor (a VLP-16 in dual mode, an Ouster or Hesai recording two echoes): a beam
// through foliage also returns the surface behind it, right after the first echo. Those second
// echoes lie behind nearer points seen from the sensor, as a merged cloud's do: 16 beams over a
// verge hold 9 % such points, past OriginView's 6 %, and the normal method judges the planes
// without the sensor, which costs a scan under the open sky nothing. Neither method may label
// the first echoes worse for the second ones beside them, nor the whole scan much worse.
TEST(UnseenSensors, SecondEchoesBehindFoliageCostTheFirstOnesNothing) {
  const std::pair<const char*, const char*> scenes[] = {
      {"lidar16:1:layout=verge", "lidar16:1:layout=verge,second_returns=1"},
      {"offroad:1", "offroad:1:second_returns=1"}};
  for (const auto& sc : scenes) {
    const GeneratedScan one = generateScene(parseSceneSpec(sc.first));
    const GeneratedScan two = generateScene(parseSceneSpec(sc.second));
    // The first echoes are the scan without second ones, in order (their noise is the same).
    std::vector<bool> first(two.size(), false);
    std::size_t matched = 0;
    for (std::size_t i = 0; i < two.size() && matched < one.size(); ++i) {
      if (std::equal(&two.xyz[3 * i], &two.xyz[3 * i + 3], &one.xyz[3 * matched])) {
        first[i] = true;
        ++matched;
      }
    }
    ASSERT_EQ(matched, one.size()) << sc.second;
    ASSERT_GT(two.size(), one.size() + one.size() / 20) << sc.second << ": few second echoes";
    const std::vector<std::int8_t> truth_one(one.truth.begin(), one.truth.end());
    for (const char* method : {"voxel", "normal"}) {
      std::vector<std::uint8_t> alone, beside;
      makeGroundFilter(method)->filter(CloudView::packedXyz(one.xyz.data(), one.size()), &alone);
      makeGroundFilter(method)->filter(CloudView::packedXyz(two.xyz.data(), two.size()), &beside);
      std::vector<std::uint8_t> beside_first;
      std::vector<std::int8_t> truth_two(two.truth.begin(), two.truth.end());
      for (std::size_t i = 0; i < two.size(); ++i) {
        if (first[i]) beside_first.push_back(beside[i]);
      }
      const double f1_alone = computeMetrics(countConfusion(alone, truth_one)).f1;
      const double f1_first = computeMetrics(countConfusion(beside_first, truth_one)).f1;
      const double f1_all = computeMetrics(countConfusion(beside, truth_two)).f1;
      std::printf("%s %s: F1 %.4f alone, first echoes %.4f, all %.4f\n", method, sc.second,
                  f1_alone, f1_first, f1_all);
      EXPECT_GT(f1_alone, 0.85) << method << " " << sc.first;
      EXPECT_GT(f1_first, f1_alone - 0.01) << method << " " << sc.second;
      EXPECT_GT(f1_all, f1_alone - 0.02) << method << " " << sc.second;
    }
  }
}

// A cloud in a frame on the ground below its sensor (base_link, base_footprint: transformed
// there upstream, the sensor 1.2-1.8 m up), or in a map frame. Seen from that origin a 16- or
// 32-beam sensor's rings part into near and far returns, no clean lines show, and the stride stayed
// at 2 (F1 72, 66, 65 here). Seen from 1.2-2.25 m above the origin the rings are lines again: the
// same F1 as in the sensor's own frame (scripts/sensor_sweep.py --base-frame).
TEST(UnseenSensors, ScansInAFrameOnTheGroundKeepTheirScanLines) {
  const std::pair<const char*, const char*> scenes[] = {
      {"lidar16:1:layout=verge,beams=32,azimuth_steps=3600,sensor_height=1.2", ",base_frame=1"},
      {"lidar16:1:layout=trail,beams=32,azimuth_steps=3600,sensor_height=1.2", ",base_frame=1"},
      {"lidar16:1:layout=trail,sensor_height=1.8", ",base_frame=1"},
      // A single scan in a map frame, its sensor 40 m from the origin (a LIO's registered scan):
      // the lines show from the ground below the densest area's centre (F1 69 before).
      {"lidar16:1:layout=trail,sensor_height=1.8,sensor_x=40", ",world_frame=1"}};
  for (const auto& sc : scenes) {
    const char* spec = sc.first;
    double f1[2];
    for (int base = 0; base < 2; ++base) {
      const std::string s = std::string(spec) + (base ? sc.second : "");
      const GeneratedScan scan = generateScene(parseSceneSpec(s));
      std::vector<std::uint8_t> labels;
      FilterStats stats;
      makeGroundFilter("normal")->filter(CloudView::packedXyz(scan.xyz.data(), scan.size()),
                                         &labels, &stats);
      const std::vector<std::int8_t> truth(scan.truth.begin(), scan.truth.end());
      f1[base] = computeMetrics(countConfusion(labels, truth)).f1;
      std::printf("%s: F1 %.4f (%s)\n", s.c_str(), f1[base], stats.note.c_str());
      EXPECT_NE(stats.note.find("sample_stride 2 -> "), std::string::npos)
          << s << ": " << stats.note;
      if (base) {
        EXPECT_NE(stats.note.find(" the origin)"), std::string::npos) << stats.note;
      }
    }
    EXPECT_GT(f1[1], f1[0] - 0.01) << spec;
  }
}

// The voxel method's start segment must pass below the sensor. In a map frame whose origin lies
// on the ground 40 m behind the scan, almost no point lies below the origin, and planes
// extrapolated under it were taken (F1 0.016 on the street): the sensor is then placed 1.5 m
// above the ground at the densest area's centre. On the trail the origin's ground lies higher
// than the scan's and 3 % of the points lie below it, so the densest cell's distance from the
// origin (over 20 m) must tell it too (F1 0.079 before).
TEST(UnseenSensors, VoxelStartSegmentInAMapFrame) {
  const char* specs[] = {
      "lidar16:1:layout=street,beams=128,vertical_min_deg=-22.5,vertical_max_deg=22.5,"
      "azimuth_steps=2048,sensor_height=0.7,sensor_x=40",
      "lidar16:2:layout=trail,beams=128,vertical_min_deg=-22.5,vertical_max_deg=22.5,"
      "azimuth_steps=2048,sensor_height=1.2,sensor_x=40"};
  for (const std::string spec : specs) {
    const Score own = run("voxel", spec);
    const Score map = run("voxel", spec + ",world_frame=1");
    EXPECT_GT(own.f1, 0.95) << spec;
    EXPECT_GT(map.f1, own.f1 - 0.01) << spec;
  }
}

// The sensor placed over the densest area's centre in a map frame sits 1.5 m above the ground
// there: sparse sensors 1.8 m up over rough ground lose their ground on both sides of the 1-2 m
// range (0.75 m and 2.5 m: F1 0.11 and 0.26 on these two, 0.88 and 0.78 inside it).
TEST(UnseenSensors, VoxelMapFrameSensorHeightOverRoughGround) {
  const char* specs[] = {
      "lidar16:2:layout=offroad,beams=16,vertical_min_deg=-15,vertical_max_deg=15,"
      "azimuth_steps=1800,sensor_height=1.8,sensor_x=40,world_frame=1",
      "lidar16:1:layout=trail,beams=16,vertical_min_deg=-15,vertical_max_deg=15,"
      "azimuth_steps=900,sensor_height=1.8,sensor_x=40,world_frame=1"};
  for (const char* spec : specs) EXPECT_GT(run("voxel", spec).f1, 0.7) << spec;
}

// A VLP-16 1.8 m over off-road ground, 40 m along the generated world's x: its rings fall apart
// into segments of at most 30 voxels, the crowns' undersides above it make the eight largest,
// and a crown's tilted plane passed below the sensor all the same (F1 2.3 % and 11.1 %). The
// start segment must also lie below the sensor.
TEST(UnseenSensors, VoxelStartSegmentLiesBelowTheSensorNotInACrown) {
  for (const char* seed : {"1", "2"}) {
    const Score s = run("voxel", std::string("lidar16:") + seed +
                                     ":layout=offroad,beams=16,vertical_min_deg=-15,"
                                     "vertical_max_deg=15,azimuth_steps=1800,sensor_height=1.8,"
                                     "sensor_x=40");
    EXPECT_GT(s.f1, 0.8) << "seed " << seed;
  }
}

// A 64-beam sensor 5 m up (a mast, a roadside pole, a truck's cab): the ground's rings lie too
// far apart to join, so each ring arc is a small segment of its own, and on the street a flat
// roof below the sensor outgrew them all (F1 0.38); off road the arcs' fitted planes were too
// steep to count, and a crown's top took the start (F1 0.02). The start segment is the largest
// of those that most flat voxels around the sensor lie level with (0.98 and 0.91 now); the
// normal method keeps its ground as well.
TEST(UnseenSensors, VoxelStartSegmentUnderAHighSensor) {
  EXPECT_GT(run("voxel", "lidar:2:sensor_height=5").f1, 0.9);
  EXPECT_GT(run("voxel", "offroad:2:sensor_height=5").f1, 0.8);
  EXPECT_GT(run("normal", "lidar:2:sensor_height=5").f1, 0.9);
}

// 32 beams from -10 to +3.3 deg (a long-range sensor) 3.5-4 m up over the street: the lowest beam
// meets the ground 20-23 m out, and the ground falls into arcs of 4-10 voxels, none among the
// larger pieces of crowns and car tops 1.5-3 m above it, whose flat voxels also outnumber the
// ground's near the sensor. The start segment was a crown or a car top (F1 0.14, 0.68 and 0.40
// with the levelling of GroundTilt.ANarrowSensorHighUpIsNotTurnedOntoObjectTops, 0.14, 0.57 and
// 0.40 without). Candidates more than 1 m above the flat voxels that the sensor sees steepest
// down now come last (0.95, 0.95, 0.96).
TEST(UnseenSensors, VoxelStartSegmentUnderANarrowSensorHighUp) {
  for (const char* spec :
       {"lidar:3:sensor_height=3.5", "lidar:6:sensor_height=3.5", "lidar:4:sensor_height=4"}) {
    const std::string narrow = std::string(spec) +
                               ",beams=32,vertical_min_deg=-10,vertical_max_deg=3.3,"
                               "uniform_beams=1,azimuth_steps=1800";
    EXPECT_GT(run("voxel", narrow).f1, 0.9) << narrow;
  }
}

// A VLP-16 (16 beams, 2 deg apart) over ground that climbs a 7 % grade, or the verge's banks:
// its rings lie 4-10 m apart there, and the next ring out lies 0.3-0.7 m above the level
// prediction the ground model carries across the gap, more than seed_window (0.2 m), so the
// model stopped at the last ring it could reach (F1 0.851, 0.903, 0.899). A prediction carried
// across cells without seeds now accepts kGapGrade (5 %) per metre more above it, at most
// kGapRise (0.3 m) (0.899, 0.934, 0.934).
TEST(UnseenSensors, VoxelGroundClimbsAGradeBetweenSparseRings) {
  const std::string vlp16 =
      ",beams=16,vertical_min_deg=-15,vertical_max_deg=15,uniform_beams=1,"
      "azimuth_steps=1800";
  EXPECT_GT(run("voxel", "lidar:3:sensor_height=3.1,slope_x=0.07,ramp_height=0" + vlp16).f1, 0.88);
  EXPECT_GT(run("voxel", "lidar:3:sensor_height=1.73,slope_x=0.07,ramp_height=0" + vlp16).f1, 0.92);
  EXPECT_GT(run("voxel", "verge:3:sensor_height=3.1" + vlp16).f1, 0.92);
}

namespace {

// Both methods on the two 16-beam streets: F1, upright points ground, road recall, and the
// stage that ran.
void expectLowestLinesOff(const char* method, double f1, double upright, double road) {
  for (const char* spec : {"lidar16:1", "lidar16:2"}) {
    FilterStats stats;
    const Score s = run(method, spec, &stats);
    EXPECT_GT(s.f1, f1) << method << " " << spec;
    EXPECT_LT(s.upright_ground, upright) << method << " " << spec;
    EXPECT_GT(s.road_recall, road) << method << " " << spec;
    bool timed = false;
    for (const auto& st : stats.stage_ms) timed = timed || st.first == "line_walls";
    EXPECT_TRUE(timed) << method << " " << spec;
  }
}

}  // namespace

// A VLP-16 0.7 m above the street (the dev group lidar16:1,2): its rings lie 2 deg apart, so
// the lowest line on a wall or a car's side lies anywhere up to 0.2-1 m above the ground and
// looked like a ring on the ground: 7.5-8 % of the car and building points were ground (F1 0.945,
// 0.947). The next line up hits the same upright surface straight above it, one line higher as
// the sensor sees it (step 10, voxel/line_walls.h): those points are now non-ground (2.5 %,
// 0.975, 0.972). A dense sensor measures no sparse lines and keeps its labels.
TEST(UnseenSensors, VoxelLowestScanLineOnAWallOrACarIsNotGround) {
  expectLowestLinesOff("voxel", 0.965, 0.04, 0.97);
}

// The same scans, the normal method: its tile planes took the same lowest lines for ground (7.9
// and 6.0 % of the car and building points, F1 0.945, 0.951). Step 7 (normal/line_walls.h), the
// per-point form of the voxel filter's step 10, makes them non-ground (1.5 %, 1.1 %; 0.979,
// 0.976) and keeps the road (97.6, 97.2 % ground).
TEST(UnseenSensors, NormalLowestScanLineOnAWallOrACarIsNotGround) {
  expectLowestLinesOff("normal", 0.965, 0.03, 0.965);
}

// 16 beams from -20 to +8 deg, 3 m up (a truck's roof): the ground starts 8 m out, and on
// some seeds the 1 m columns read as a side view (scan_type auto, rule 4: registered). The
// voxel method then had no sensor to start below and took a roof or a wall's line for the
// ground (F1 0.90 and 0.18). Seen from the origin, 1 % of the points lie behind nearer ones:
// one scan, whose start segment passes below its sensor (0.92, 0.93).
TEST(UnseenSensors, VoxelStartBelowTheSensorOfASideViewSeenWhole) {
  for (int seed : {10, 21}) {
    const std::string spec = "lidar16:" + std::to_string(seed) +
                             ":sensor_height=3,vertical_min_deg=-20,vertical_max_deg=7.9,"
                             "azimuth_steps=1024";
    FilterStats stats;
    EXPECT_GT(run("voxel", spec, &stats).f1, 0.9) << spec;
    EXPECT_NE(stats.scan_reason.find("side view"), std::string::npos) << stats.scan_reason;
  }
}

// Sparse sensors 3-4 m up (16 or 32 beams, 512 firings a turn, the lowest beam 11-23 deg down):
// their ground starts 8-20 m out with points 10-25 cm apart along each ring, so hardly a
// 0.1 m seed voxel holds the two points the flatness test needs (0.1-2 % of them are flat;
// every scan of the dev data 15 % or more), the ground forms no segment and the model started
// on a crown or a roof (F1 0.02, 0.12, 0.61). The voxels are made 0.2, then 0.3 m wide for such
// a scan (0.88, 0.93, 0.92), and the stats say so.
TEST(UnseenSensors, VoxelsGrowCoarserOnASparseScan) {
  for (const char* spec :
       {"trail:28:sensor_height=3.8,beams=16,vertical_min_deg=-22.7,vertical_max_deg=5.8,"
        "uniform_beams=1,azimuth_steps=512",
        "lidar16:26:sensor_height=3.25,vertical_min_deg=-19.8,vertical_max_deg=3.1,"
        "azimuth_steps=512",
        "lidar16:23:sensor_height=3.8,beams=32,vertical_min_deg=-10.8,vertical_max_deg=8.1,"
        "azimuth_steps=512"}) {
    FilterStats stats;
    EXPECT_GT(run("voxel", spec, &stats).f1, 0.85) << spec;
    EXPECT_NE(stats.note.find("voxel_size 0."), std::string::npos) << stats.note;
  }
  FilterStats dense;  // a dense scan keeps its voxels
  EXPECT_GT(run("voxel", "lidar16:1", &dense).f1, 0.9);
  EXPECT_EQ(dense.note.find("voxel_size"), std::string::npos) << dense.note;
}

// 16 beams from -11 to +15 deg, 3.4 m up (a bus's roof, a mast) over a street on rolling
// ground: the ground starts 17 m out with its rings 3-14 m apart, so a ring's K nearest points
// lie on that ring and give no normal. Its far tiles took the cloud-wide plane of the near road,
// 1-3 m off the terrain there (F1 0.62). A sparse tile's floor may now lie a tenth of its
// distance off that plane, where it lies under the sensor and fills most of its tile (0.86).
// Far out a single scan line across a crown or a wall fills its tile too: above the sensor it
// keeps the near reach (before that test: 97 crown points of the 16-beam streets were ground).
TEST(UnseenSensors, NormalSparseTileFloorFollowsTerrainFarFromAHighSensor) {
  EXPECT_GT(run("normal",
                "lidar:33:sensor_height=3.39,beams=16,vertical_min_deg=-11.1,"
                "vertical_max_deg=15.2,uniform_beams=1,azimuth_steps=1024")
                .f1,
            0.8);
  for (const char* spec : {"lidar16:1", "lidar16:2"}) {
    const Score s = run("normal", spec);
    EXPECT_GT(s.f1, 0.94) << spec;
    EXPECT_LT(s.crown_ground, 10u) << spec;
  }
}

// An airborne tile's hall 80 m across, its roof in thirds 3 m apart in height, crossed by a
// strip 4 m wide without returns through the raised bay to the hall's edges (the scene of
// docs/evaluation.md, "Parts narrower than the opening, and strips without returns"). The strip
// has no roof return; the roof is not ground with either method (before the rule for regions
// narrower than the opening, 83 % of the hall's returns were ground on this seed).
TEST(UnseenSensors, AirborneHallWithAStripWithoutReturnsIsNotGround) {
  const std::string spec = "airborne:1:airborne_hall=80,airborne_hall_step=3,airborne_hall_gap=4";
  const GeneratedScan scan = generateScene(parseSceneSpec(spec));
  const CloudView view = CloudView::packedXyz(scan.xyz.data(), scan.size());
  auto onRoof = [&scan](std::size_t i) {
    const float* q = &scan.xyz[3 * i];
    return scan.semantic[i] == kClassBuilding && std::fabs(q[0]) < 38.f && std::fabs(q[1]) < 38.f;
  };
  std::size_t roof = 0, in_strip = 0;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!onRoof(i)) continue;
    ++roof;
    in_strip += std::fabs(scan.xyz[3 * i]) < 2.f;
  }
  EXPECT_GT(roof, 8000u);
  EXPECT_EQ(in_strip, 0u);
  for (const char* method : {"voxel", "normal"}) {
    std::vector<std::uint8_t> labels;
    makeGroundFilter(method)->filter(view, &labels, nullptr);
    std::size_t roof_ground = 0;
    for (std::size_t i = 0; i < scan.size(); ++i) roof_ground += onRoof(i) && labels[i] == 1;
    EXPECT_LT(roof_ground, roof / 50) << method;
  }
  for (const char* bad : {"airborne:1:airborne_hall_gap=-1", "airborne:1:airborne_hall_gap=41"}) {
    EXPECT_THROW(generateScene(parseSceneSpec(bad)), std::invalid_argument) << bad;
  }
}

}  // namespace
}  // namespace ground_filter
