// GPU tests of the whole normal-vector filter on the device (CudaNormalPipeline behind
// knn_backend gpu): labels against the kd-tree backend on KITTI / Ouster frames, dense columns,
// sparse scan lines, parking levels (a ceiling above the sensor), 1 M and 5 M points, bad input
// (packed x y z and 16-byte records), device memory across 1,000 scans, out-of-memory fallback.

#include <cuda_runtime.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "brute_force_knn.h"
#include "eval/scene_generator.h"
#include "gpu_normal_executor.h"
#include "gpu_test.h"
#include "ground_filter/cuda_knn.h"
#include "ground_filter/cuda_normal_pipeline.h"
#include "ground_filter/normal_ground_filter.h"
#include "knn/kdtree_neighbor_search.h"
#include "normal/normal_settings.h"
#include "replicate_frames.h"

namespace gf = ground_filter;

namespace {

std::vector<float> frame(const std::string& name) {
  return gf_test::readKittiBin(std::string(GF_DATA_DIR) + "/" + name);
}

/// `n` points: KITTI frames 0..5 cycled, copy t shifted by 200 m steps on a 7-wide x/y grid.
std::vector<float> replicated(std::size_t n) {
  std::vector<std::vector<float>> frames;
  for (int f = 0; f < 6; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.bin", f);
    auto xyz = frame(name);
    if (!xyz.empty()) frames.push_back(std::move(xyz));
  }
  return gf_test::replicateFrames(frames, n);
}

struct Compared {
  std::size_t differ = 0, ground_gpu = 0, ground_cpu = 0;
  gf::FilterStats sg, sc;
};

/// Runs the GPU and kd-tree backends on `xyz` with `p` (backend overridden). `records16`: the
/// points as 16-byte records x y z w (w NaN on every other point: never read as a coordinate),
/// the layout the GPU's host packing loads 16 bytes at a time; else packed x y z triplets.
Compared compare(const std::vector<float>& xyz, gf::NormalGroundFilterParams p,
                 std::vector<std::uint8_t>* lg_out = nullptr, bool records16 = false) {
  const std::size_t n = xyz.size() / 3;
  std::vector<float> rec;
  if (records16) {
    rec.resize(4 * n);
    for (std::size_t i = 0; i < n; ++i) {
      std::copy_n(&xyz[3 * i], 3, &rec[4 * i]);
      rec[4 * i + 3] = (i % 2) ? std::numeric_limits<float>::quiet_NaN() : 1.f;
    }
  }
  const auto cloud = records16 ? gf::CloudView(rec.data(), n, 4 * sizeof(float))
                               : gf::CloudView::packedXyz(xyz.data(), n);
  gf::NormalGroundFilterParams pg = p, pc = p;
  pg.knn_backend = "gpu";
  pc.knn_backend = "kdtree";
  gf::NormalGroundFilter fg(pg), fc(pc);
  std::vector<std::uint8_t> lg, lc;
  Compared r;
  fg.filter(cloud, &lg, &r.sg);
  fc.filter(cloud, &lc, &r.sc);
  EXPECT_EQ(lg.size(), n);
  EXPECT_EQ(lc.size(), n);
  for (std::size_t i = 0; i < n && i < lg.size() && i < lc.size(); ++i) {
    r.differ += lg[i] != lc[i];
    r.ground_gpu += lg[i] == gf::kGround;
    r.ground_cpu += lc[i] == gf::kGround;
  }
  if (lg_out) *lg_out = lg;
  return r;
}

// F1 of `labels` (kGround = ground) against a generated scene's `truth` (1 = ground).
double f1Of(const std::vector<std::uint8_t>& labels, const std::vector<std::uint8_t>& truth) {
  std::size_t tp = 0, fp = 0, fn = 0;
  for (std::size_t i = 0; i < truth.size() && i < labels.size(); ++i) {
    const bool g = labels[i] == gf::kGround;
    tp += g && truth[i];
    fp += g && !truth[i];
    fn += !g && truth[i];
  }
  return 2.0 * tp / std::max<double>(1.0, 2.0 * tp + fp + fn);
}

using GpuPipelineTest = gf_test::GpuTest;

TEST_F(GpuPipelineTest, DevFramesGiveTheKdTreeLabels) {
  std::size_t total = 0, differ = 0;
  for (const char* name : {"000000.bin", "000001.bin", "000002.bin", "000003.bin", "000004.bin",
                           "000005.bin", "os128_000000.bin"}) {
    const auto xyz = frame(name);
    if (xyz.empty()) {
      ADD_FAILURE() << "missing " << GF_DATA_DIR << "/" << name;
      continue;
    }
    const Compared c = compare(xyz, gf::NormalGroundFilterParams());
    EXPECT_EQ(c.sg.backend, "gpu") << c.sg.note;
    EXPECT_EQ(c.sg.ground_points, c.ground_gpu);
    EXPECT_EQ(c.sg.invalid_points, c.sc.invalid_points);
    EXPECT_GT(c.ground_cpu, xyz.size() / 3 / 10);
    std::printf("[ FILTER   ] %s: %zu points, %zu labels differ; ground GPU %zu, CPU %zu\n", name,
                xyz.size() / 3, c.differ, c.ground_gpu, c.ground_cpu);
    total += xyz.size() / 3;
    differ += c.differ;
  }
  EXPECT_LE(differ * 10000, total) << differ << " of " << total << " labels differ";
}

// Parking levels (builtin:garage and other sensors there): no ground plane passes above the
// sensor, on the GPU as on the CPU; the ceiling stays non-ground (test_unseen_sensors: the CPU).
TEST_F(GpuPipelineTest, CeilingScenesGiveTheKdTreeLabels) {
  struct Case {
    const char* spec;
    std::size_t ceiling_share;  // at most 1 / this of the ceiling ground (as on the CPU)
  };
  // The last two have no sensor to judge planes by (registered; a 4 m ceiling read as one):
  // the voted points over others are left out (normal::overheadPoint()); where no floor is seen
  // under the ceiling it may stay ground (the 4 m level seen from 1.8 m: a fifth of it).
  for (const Case& cs :
       {Case{"garage:1", 33}, Case{"garage:2", 33}, Case{"garage:1:sensor_height=0.5", 33},
        Case{"tls:1:layout=garage,tls_points=300000", 33}, Case{"rosette:1:layout=garage", 33},
        Case{"stations:1:layout=garage,tls_points=300000", 10},
        Case{"garage:1:ceiling_height=4", 4}}) {
    const gf::GeneratedScan scan = gf::generateScene(gf::parseSceneSpec(cs.spec));
    std::vector<std::uint8_t> lg;
    const Compared c = compare(scan.xyz, gf::NormalGroundFilterParams(), &lg);
    EXPECT_EQ(c.sg.backend, "gpu") << c.sg.note;
    std::size_t ceiling = 0, ceiling_ground = 0;
    for (std::size_t i = 0; i < scan.size(); ++i) {
      if (scan.semantic[i] != gf::kClassBuilding || !(scan.xyz[3 * i + 2] > 0.5f)) continue;
      ++ceiling;
      ceiling_ground += lg[i] == gf::kGround;
    }
    std::printf("[ FILTER   ] %s: %zu points, %zu labels differ; ceiling %zu of %zu ground\n",
                cs.spec, scan.size(), c.differ, ceiling_ground, ceiling);
    EXPECT_LE(c.differ * 10000, scan.size()) << cs.spec;
    EXPECT_LT(ceiling_ground, ceiling / cs.ceiling_share) << cs.spec;
  }
}

// A car in the next lane beside the sensor (test_unseen_sensors: the CPU): its bonnet and roof
// fill their tile, and the tile's plane stood on them until the raised-tile test
// (normal::raisedTileMedian(), the GPU's raisedTilesKernel) labels the tile against its
// neighbours' plane. The GPU gives the CPU's labels, with the car off the ground.
TEST_F(GpuPipelineTest, CarBesideTheSensorGivesTheKdTreeLabels) {
  for (const char* spec : {"lidar:1:beside_car=3.6", "lidar:2:beside_car=3.6", "lidar:32"}) {
    const gf::GeneratedScan scan = gf::generateScene(gf::parseSceneSpec(spec));
    std::vector<std::uint8_t> lg;
    const Compared c = compare(scan.xyz, gf::NormalGroundFilterParams(), &lg);
    EXPECT_EQ(c.sg.backend, "gpu") << c.sg.note;
    const double f1 = f1Of(lg, scan.truth);
    std::printf("[ FILTER   ] %s: %zu points, %zu labels differ; GPU F1 %.4f\n", spec, scan.size(),
                c.differ, f1);
    EXPECT_LE(c.differ * 10000, scan.size()) << spec;
    EXPECT_GT(f1, 0.955) << spec;
  }
}

// The sparse-tile floor's far reach (normal::floorReach(), floorShare()): a 16-beam sensor
// 3.4 m up whose far ground lies 1-3 m off the cloud-wide plane (F1 0.62 without the reach,
// 0.86 with it; test_unseen_sensors: the CPU) and a 16-beam street whose far crowns stay off.
// Both sparse: the host's step 7 (normal/line_walls.h) follows the pipeline, and the street's
// lowest lines on walls and cars leave the ground (F1 0.951 without it, 0.979 with it).
TEST_F(GpuPipelineTest, FarFloorScenesGiveTheKdTreeLabels) {
  struct Case {
    const char* spec;
    double min_f1;  // of the GPU's labels
  };
  for (const Case& cs : {Case{"lidar:33:sensor_height=3.39,beams=16,vertical_min_deg=-11.1,"
                              "vertical_max_deg=15.2,uniform_beams=1,azimuth_steps=1024",
                              0.8},
                         Case{"lidar16:1", 0.97}}) {
    const gf::GeneratedScan scan = gf::generateScene(gf::parseSceneSpec(cs.spec));
    std::vector<std::uint8_t> lg;
    const Compared c = compare(scan.xyz, gf::NormalGroundFilterParams(), &lg);
    EXPECT_EQ(c.sg.backend, "gpu") << c.sg.note;
    const double f1 = f1Of(lg, scan.truth);
    // The GPU filter's time on this scan (a report, not a test: medians of 15 calls after one),
    // and the host's step 7 in it (its column order included).
    gf::NormalGroundFilterParams pg;
    pg.knn_backend = "gpu";
    gf::NormalGroundFilter fg(pg);
    const gf::CloudView view = gf::CloudView::packedXyz(scan.xyz.data(), scan.size());
    std::vector<double> total, walls_ms;
    for (int r = 0; r < 16; ++r) {
      gf::FilterStats st;
      fg.filter(view, &lg, &st);
      double w = 0.0;
      for (const auto& s : st.stage_ms) w += s.first == "line_walls" ? s.second : 0.0;
      if (r > 0) total.push_back(st.total_ms), walls_ms.push_back(w);
    }
    std::sort(total.begin(), total.end());
    std::sort(walls_ms.begin(), walls_ms.end());
    std::printf(
        "[ FILTER   ] %s: %zu points, %zu labels differ; GPU F1 %.4f; GPU filter %.2f ms "
        "(median of 15), of which line_walls on the host %.2f ms\n",
        cs.spec, scan.size(), c.differ, f1, total[7], walls_ms[7]);
    EXPECT_LE(c.differ * 10000, scan.size()) << cs.spec;
    EXPECT_GT(f1, cs.min_f1) << cs.spec;
    bool walls = false;
    for (const auto& st : c.sg.stage_ms) walls = walls || st.first == "line_walls";
    EXPECT_TRUE(walls) << cs.spec << ": " << c.sg.note;
  }
}

TEST_F(GpuPipelineTest, FilterOptionsGiveTheKdTreeLabels) {
  const auto xyz = frame("000001.bin");
  ASSERT_FALSE(xyz.empty());
  struct Case {
    const char* what;
    gf::NormalGroundFilterParams p;
  };
  // Each case: the defaults with the parameters it names ("name=value ...", set()).
  std::vector<Case> cases;
  for (const char* what :
       {"local_planes=false", "std_filter=true", "bayes_vote=false plane_all_points=false",
        "k=20 min_planarity=0.3 tile_size=10", "k=64 ransac_iterations=20", "ransac_seed=7",
        "local_planes=false ransac_seed=7", "sample_stride=1 k=64",
        "sample_stride=3 k=24 plane_all_points=false", "sample_stride=3 k=28"}) {
    Case cs{what, {}};
    std::istringstream items(what);
    for (std::string item; items >> item;) {
      const std::size_t eq = item.find('=');
      cs.p.set(item.substr(0, eq), item.substr(eq + 1));
    }
    cases.push_back(cs);
  }
  for (const auto& cs : cases) {
    const Compared c = compare(xyz, cs.p);
    EXPECT_EQ(c.sg.backend, "gpu") << cs.what << ": " << c.sg.note;
    EXPECT_LE(c.differ * 10000, xyz.size() / 3) << cs.what << ": " << c.differ << " differ";
    std::printf("[ FILTER   ] %s: %zu labels differ; ground GPU %zu, CPU %zu\n", cs.what, c.differ,
                c.ground_gpu, c.ground_cpu);
  }
}

TEST_F(GpuPipelineTest, DenseColumnsGiveTheKdTreeLabels) {
  // A TLS station's ground near its tripod: 200,000 points on a 1 m disc in a KITTI frame, about
  // 640 a 0.1 m column, far over sample_stride x columnSampleCap(k): every such column takes the
  // capped sample (normal/sample.h), which the GPU computes from its sorted column keys.
  auto xyz = frame("000000.bin");
  ASSERT_FALSE(xyz.empty());
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::normal_distribution<float> noise(0.f, 0.01f);
  for (int added = 0; added < 200000;) {
    const float x = u(rng), y = u(rng);
    if (x * x + y * y > 1.f) continue;
    xyz.insert(xyz.end(), {x + 5.f, y, -1.73f + noise(rng)});
    ++added;
  }
  for (const char* what : {"", "local_planes=false", "sample_stride=3 k=24", "k=64"}) {
    gf::NormalGroundFilterParams p;
    p.scan_type = "ground";  // the GPU pipeline, whatever scan_type auto makes of the disc
    std::istringstream items(what);
    for (std::string item; items >> item;) {
      const std::size_t eq = item.find('=');
      p.set(item.substr(0, eq), item.substr(eq + 1));
    }
    const Compared c = compare(xyz, p);
    EXPECT_EQ(c.sg.backend, "gpu") << what << ": " << c.sg.note;
    EXPECT_LE(c.differ * 10000, xyz.size() / 3) << what << ": " << c.differ << " differ";
    EXPECT_GT(c.ground_cpu, 200000u) << what;  // the disc is ground
    std::printf("[ FILTER   ] dense disc, '%s': %zu labels differ; ground GPU %zu, CPU %zu\n", what,
                c.differ, c.ground_gpu, c.ground_cpu);
  }
}

TEST_F(GpuPipelineTest, SparseScanLinesWidenTheStrideAsOnTheCpu) {
  // A VLP-16's scan: rings 2 deg apart, 0.2 deg a firing, 1.8 m above flat ground inside a round
  // wall 25 m away (6 rings on the ground, 10,800 points). The default stride leaves each K
  // neighbourhood on one ring: no candidates, until max_line_ratio (common/scan_lines.h) or
  // min_candidate_share (normal::sparseLinesStride()) has doubled the stride; for the latter the
  // GPU decides on its own count, as the CPU does. (At 0.1 deg a firing, stride 4 leaves the
  // neighbourhoods nearly degenerate, and the CPU's and the GPU's candidate counts there fell on
  // either side of the share: 2 -> 8 against 2 -> 4.)
  std::vector<float> xyz;
  std::size_t ground_truth = 0;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.02);  // range noise (exact lines are degenerate)
  for (int b = 0; b < 16; ++b) {
    const double el = (-15.0 + 2.0 * b) * M_PI / 180.0;
    for (int a = 0; a < 1800; ++a) {
      const double az = a * 0.2 * M_PI / 180.0;
      const double dz = std::sin(el);
      double t = 25.0 / std::cos(el);
      if (dz < 0.0 && 1.8 / -dz < t) {
        t = 1.8 / -dz;
        ++ground_truth;
      }
      t += noise(rng);
      xyz.insert(xyz.end(),
                 {static_cast<float>(t * std::cos(el) * std::cos(az)),
                  static_cast<float>(t * std::cos(el) * std::sin(az)), static_cast<float>(t * dz)});
    }
  }
  ASSERT_EQ(ground_truth, 10800u);
  auto strides = [](const std::string& note) {  // "sample_stride A -> B"
    const std::size_t at = note.find("sample_stride");
    return at == std::string::npos ? std::string() : note.substr(at, note.find(':', at) - at);
  };
  // The defaults: the measured lines widen the stride before the normals (on the host, for
  // both); max_line_ratio 0: the candidates' share widens it after them, each on its own count.
  for (const char* rule : {"scan lines", "min_candidate_share"}) {
    gf::NormalGroundFilterParams p;
    p.scan_type = "ground";
    if (rule[0] == 'm') p.max_line_ratio = 0.0;
    const Compared c = compare(xyz, p);
    EXPECT_EQ(c.sg.backend, "gpu") << c.sg.note;
    EXPECT_LE(c.differ * 10000, xyz.size() / 3) << rule << ": " << c.differ << " differ";
    EXPECT_NE(c.sc.note.find("sample_stride 2 -> 4"), std::string::npos) << c.sc.note;
    EXPECT_NE(c.sc.note.find(rule), std::string::npos) << c.sc.note;
    EXPECT_NE(c.sg.note.find(rule), std::string::npos) << c.sg.note;
    EXPECT_EQ(strides(c.sg.note), strides(c.sc.note)) << c.sg.note;
    EXPECT_GE(c.ground_cpu, ground_truth * 9 / 10);  // without either rule: none
    EXPECT_LT(c.ground_cpu, ground_truth + 1000);    // the wall's foot at most
    std::printf("[ FILTER   ] sparse rings (%s): %zu labels differ; ground GPU %zu, CPU %zu; %s\n",
                rule, c.differ, c.ground_gpu, c.ground_cpu, c.sg.note.c_str());
  }
}

TEST_F(GpuPipelineTest, LargeCloudsGiveTheKdTreeLabels) {
  for (std::size_t n : {std::size_t(1000000), std::size_t(5000000)}) {
    const auto xyz = replicated(n);
    ASSERT_EQ(xyz.size(), 3 * n);
    // KITTI frames side by side are many sensors' scans, not one: scan_type auto may take the
    // airborne mode (CPU only) for them, so the ground-level pipeline is asked for.
    gf::NormalGroundFilterParams p;
    p.scan_type = "ground";
    const Compared c = compare(xyz, p);
    EXPECT_EQ(c.sg.backend, "gpu") << c.sg.note;
    EXPECT_EQ(c.sg.scan_type, "ground");
    EXPECT_LE(c.differ * 10000, n) << c.differ << " labels differ";
    std::printf(
        "[ 5M       ] %zu points: %zu labels differ; ground GPU %zu, CPU %zu; GPU %.1f ms, "
        "kd-tree %.1f ms\n",
        n, c.differ, c.ground_gpu, c.ground_cpu, c.sg.total_ms, c.sc.total_ms);
  }
}

TEST_F(GpuPipelineTest, BadInputGivesTheKdTreeLabels) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const auto kitti = frame("000000.bin");
  ASSERT_FALSE(kitti.empty());
  std::vector<std::pair<std::string, std::vector<float>>> clouds;
  for (std::size_t m : {1, 2, 3, 10, 49, 50, 51}) {  // fewer points than K and around it
    clouds.emplace_back("first " + std::to_string(m) + " points",
                        std::vector<float>(kitti.begin(), kitti.begin() + 3 * m));
  }
  clouds.emplace_back("one point 1000 times", std::vector<float>());
  for (int i = 0; i < 1000; ++i) clouds.back().second.insert(clouds.back().second.end(), {1, 2, 3});
  clouds.emplace_back("5 points 400 times each", std::vector<float>());
  for (int i = 0; i < 2000; ++i) {
    const float x = static_cast<float>(i % 5);
    clouds.back().second.insert(clouds.back().second.end(),
                                {x, static_cast<float>((i % 5) * (i % 5) % 3), -1.7f});
  }
  clouds.emplace_back("a KITTI frame twice", kitti);
  clouds.back().second.insert(clouds.back().second.end(), kitti.begin(), kitti.end());
  clouds.emplace_back("all NaN", std::vector<float>(3000, nan));
  clouds.emplace_back("NaN and Inf mixed in", kitti);
  for (std::size_t i = 0; i < kitti.size() / 3; i += 7) {
    clouds.back().second[3 * i + i % 3] = (i % 2) ? nan : ((i % 4) ? inf : -inf);
  }
  clouds.emplace_back("a line of points", std::vector<float>());
  for (int i = 0; i < 5000; ++i) {
    clouds.back().second.insert(clouds.back().second.end(), {0.01f * i, 0.f, 0.f});
  }
  clouds.emplace_back("huge coordinates", std::vector<float>());
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1e15f, 1e15f);
  for (int i = 0; i < 3000; ++i) {
    clouds.back().second.insert(clouds.back().second.end(), {u(rng), u(rng), u(rng)});
  }
  for (const auto& c : clouds) {
    for (const bool records16 : {false, true}) {
      const Compared r = compare(c.second, gf::NormalGroundFilterParams(), nullptr, records16);
      EXPECT_EQ(r.differ, 0u) << c.first << (records16 ? ", 16-byte records" : "");
      EXPECT_EQ(r.sg.backend, "gpu") << c.first << ": " << r.sg.note;
      EXPECT_EQ(r.sg.invalid_points, r.sc.invalid_points) << c.first;
      EXPECT_EQ(r.sg.ground_points, r.sc.ground_points) << c.first;
    }
  }
  // Empty cloud.
  gf::NormalGroundFilterParams p;
  p.knn_backend = "gpu";
  gf::NormalGroundFilter f(p);
  std::vector<std::uint8_t> labels(5, 9);
  f.filter(gf::CloudView(), &labels);
  EXPECT_TRUE(labels.empty());
}

TEST_F(GpuPipelineTest, NoDeviceMemoryGrowthOver1000Scans) {
  const auto kitti = frame("000000.bin");
  ASSERT_FALSE(kitti.empty());
  const std::size_t n_max = kitti.size() / 3;
  gf::NormalGroundFilterParams p;
  p.knn_backend = "gpu";
  gf::NormalGroundFilter f(p);
  std::vector<std::uint8_t> labels;
  gf::FilterStats st;
  f.filter(gf::CloudView::packedXyz(kitti.data(), n_max), &labels, &st);  // largest first
  ASSERT_EQ(st.backend, "gpu") << st.note;
  ASSERT_EQ(cudaDeviceSynchronize(), cudaSuccess);
  std::size_t free0 = 0, free1 = 0, total = 0;
  ASSERT_EQ(cudaMemGetInfo(&free0, &total), cudaSuccess);
  std::mt19937 rng(11);
  std::uniform_int_distribution<std::size_t> size(0, n_max);
  std::size_t on_gpu = 0;
  for (int s = 0; s < 1000; ++s) {
    const std::size_t m = size(rng);
    const std::size_t off = (n_max - m) / 2;
    f.filter(gf::CloudView::packedXyz(kitti.data() + 3 * off, m), &labels, &st);
    on_gpu += st.backend == "gpu";
    ASSERT_EQ(labels.size(), m);
  }
  ASSERT_EQ(cudaDeviceSynchronize(), cudaSuccess);
  ASSERT_EQ(cudaMemGetInfo(&free1, &total), cudaSuccess);
  EXPECT_EQ(on_gpu, 1000u);
  EXPECT_EQ(free1, free0) << "device memory free before " << free0 << ", after " << free1;
  std::printf("[ FILTER   ] 1000 scans of 0..%zu points: device free %zu -> %zu bytes\n", n_max,
              free0, free1);
}

TEST_F(GpuPipelineTest, OutOfMemoryFallsBackToTheKdTreeForThatScan) {
  const auto xyz = frame("000000.bin");
  ASSERT_FALSE(xyz.empty());
  const auto cloud = gf::CloudView::packedXyz(xyz.data(), xyz.size() / 3);
  gf::CudaKnnOptions opt;
  opt.memory_limit = 1 << 20;  // the pipeline cannot take this scan
  gf::NormalGroundFilterParams p;
  p.knn_backend = "gpu";
  gf::NormalGroundFilter fg(p, std::make_unique<gf::KdTreeNeighborSearch>(0),
                            std::make_unique<gf::GpuNormalExecutor>(
                                gf::CudaNormalParams(p, gf::normal::minAbsNormalZ(p)), opt));
  p.knn_backend = "kdtree";
  gf::NormalGroundFilter fc(p);
  std::vector<std::uint8_t> lg, lc;
  gf::FilterStats sg, sc;
  for (int scan = 0; scan < 2; ++scan) {  // every scan tries the GPU again, and falls back again
    fg.filter(cloud, &lg, &sg);
    EXPECT_EQ(sg.backend, "kdtree");
    EXPECT_NE(sg.note.find("GPU filter failed (cudaErrorMemoryAllocation"), std::string::npos)
        << sg.note;
    EXPECT_EQ(sg.note.find("GPU filter failed", 1), std::string::npos) << "one reason: " << sg.note;
  }
  fc.filter(cloud, &lc, &sc);
  EXPECT_EQ(lg, lc);
  EXPECT_EQ(sg.ground_points, sc.ground_points);
  // The pipeline itself reports the error as a CudaError.
  gf::CudaNormalPipeline pipeline(opt);
  std::vector<std::uint8_t> labels(xyz.size() / 3);
  try {
    pipeline.run(cloud, gf::CudaNormalParams(), labels.data());
    FAIL() << "ran within 1 MiB";
  } catch (const gf::CudaError& e) {
    EXPECT_EQ(e.errorName(), "cudaErrorMemoryAllocation");
  }
}

}  // namespace
