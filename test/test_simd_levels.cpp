// Every filter under every SIMD level this machine runs (simd::supported(): portable, sse, avx2,
// avx512 on x86-64; portable, neon on aarch64): labels byte-identical to the portable path's on
// a KITTI frame (or a generated scan without the data), on bad input (fewer points than K, all
// points identical, NaN/Inf mixed in, 5 M points), and no allocation per scan after the first.
// Also GF_SIMD itself: names, unknown and unsupported values, and one child process per case.
// ROS- and PCL-free: scripts/check_arm64.sh builds and runs it for aarch64 under qemu.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <memory>
#include <new>
#include <random>
#include <string>
#include <vector>

#include "eval/scene_generator.h"
#include "gf_test_alloc_counter.h"  // allocationCount()
#include "ground_filter/build_info.h"
#include "ground_filter/ground_filter.h"
#include "normal/cell_keys.h"
#include "normal/cpu_gpu_common.h"
#include "simd/simd.h"

namespace gf = ground_filter;
namespace simd = ground_filter::simd;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// The levels this build and CPU run, lowest (portable) first.
std::vector<simd::Level> levels() {
  std::vector<simd::Level> out;
  for (simd::Level l : {simd::Level::kPortable, simd::Level::kSse, simd::Level::kNeon,
                        simd::Level::kAvx2, simd::Level::kAvx512}) {
    if (simd::supported(l)) out.push_back(l);
  }
  return out;
}

// A filter as the tools make it (makeGroundFilter: the working-volume wrapper included).
struct FilterCase {
  const char* name;
  const char* method;
  gf::ParamSettings settings;
  // No allocation on a scan after the first (every case; counted, asserted and printed).
  bool allocation_free = true;
};

std::vector<FilterCase> filterCases() {
  return {
      {"voxel", "voxel", {}},
      // config/airborne.yaml: the morphological ground surface
      {"voxel_airborne",
       "voxel",
       {{"morph_ground", "true"},
        {"morph_cell", "1.0"},
        {"morph_slope", "0.15"},
        {"morph_window", "18.0"},
        {"morph_scale", "1.25"},
        {"plane_distance", "0.5"}}},
      {"voxel_one_plane", "voxel", {{"local_planes", "false"}}},
      {"normal_kdtree", "normal", {{"knn_backend", "kdtree"}, {"threads", "2"}}},
      // the optional stages: the bush-base rule, the paper's segments of grid columns
      {"normal_veg_filter",
       "normal",
       {{"knn_backend", "kdtree"}, {"threads", "2"}, {"veg_filter", "true"}}},
      {"normal_segments",
       "normal",
       {{"knn_backend", "kdtree"}, {"threads", "2"}, {"use_segments", "true"}}},
  };
}

// Records of 16 bytes (x y z intensity), as KITTI's .bin files and most drivers give them: the
// SSE levels read them in place, portable through its copy.
struct Cloud {
  std::vector<float> rec;  // 4 floats a point
  std::size_t size() const { return rec.size() / 4; }
  gf::CloudView view() const {
    return gf::CloudView(rec.data(), size(), 4 * sizeof(float), 0, sizeof(float),
                         2 * sizeof(float));
  }
  void add(float x, float y, float z) { rec.insert(rec.end(), {x, y, z, 0.5f}); }
};

// KITTI seq00 000000, or the generated 64-beam street scan when the data is not there.
const Cloud& realScan(std::string* source) {
  static std::string from;
  static const Cloud cloud = [] {
    Cloud c;
    const std::string path = std::string(GF_DATA_DIR) + "/semantickitti/seq00/000000.bin";
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (in) {
      c.rec.resize(static_cast<std::size_t>(in.tellg()) / sizeof(float) / 4 * 4);
      in.seekg(0);
      in.read(reinterpret_cast<char*>(c.rec.data()),
              static_cast<std::streamsize>(c.rec.size() * sizeof(float)));
      from = path;
      return c;
    }
    const gf::GeneratedScan s = gf::generateScene(gf::builtinSceneParams("lidar"));
    for (std::size_t i = 0; i < s.size(); ++i) {
      c.add(s.xyz[3 * i], s.xyz[3 * i + 1], s.xyz[3 * i + 2]);
    }
    from = "generated lidar scene (data not found: " + path + ")";
    return c;
  }();
  if (source) *source = from;
  return cloud;
}

// Rolling terrain with a box every 10 m, `n` points on a square grid (deterministic, fast to
// make: no ray casting).
Cloud largeTerrain(std::size_t n) {
  Cloud c;
  c.rec.reserve(4 * n);
  const std::size_t side = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(n))));
  const float step = 0.05f;
  for (std::size_t i = 0; c.size() < n; ++i) {
    const float x = static_cast<float>(i % side) * step, y = static_cast<float>(i / side) * step;
    float z = 0.4f * std::sin(0.05f * x) + 0.3f * std::cos(0.07f * y);
    const float bx = std::fmod(x, 10.f), by = std::fmod(y, 10.f);
    if (bx > 4.f && bx < 6.f && by > 4.f && by < 5.f) z += 1.5f;  // a box roof
    // a little deterministic roughness (a hash of i), so no two rows are alike
    z += 0.004f * static_cast<float>((i * 2654435761u >> 16) % 5);
    c.add(x, y, z);
  }
  return c;
}

struct ScanRun {
  std::vector<std::uint8_t> labels;
  std::size_t allocations_after_first = 0;
};

// Labels of `cloud` at `level`; with `twice`, a second scan with the same filter must allocate
// nothing and give the same labels.
ScanRun runAt(const FilterCase& fc, simd::Level level, const Cloud& cloud, bool twice) {
  simd::ScopedLevel scoped(level);
  EXPECT_TRUE(scoped.ok()) << simd::levelName(level);
  std::unique_ptr<gf::GroundFilter> f = gf::makeGroundFilter(fc.method, fc.settings);
  ScanRun r;
  f->filter(cloud.view(), &r.labels);
  if (twice) {
    std::vector<std::uint8_t> again(cloud.size(), 7);  // allocated before counting
    const std::size_t before = allocationCount().load();
    f->filter(cloud.view(), &again);
    r.allocations_after_first = allocationCount().load() - before;
    EXPECT_EQ(r.labels, again) << fc.name << " at " << simd::levelName(level)
                               << ": second scan differs";
  }
  return r;
}

std::size_t differences(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
  if (a.size() != b.size()) return std::max(a.size(), b.size());
  std::size_t d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d += a[i] != b[i];
  return d;
}

// Every level's labels equal portable's; labels are 0/1, non-finite points 0; no allocation on
// the second scan (when `twice`).
void expectSameAtEveryLevel(const Cloud& cloud, const std::string& what, bool twice = true) {
  for (const FilterCase& fc : filterCases()) {
    const ScanRun ref = runAt(fc, simd::Level::kPortable, cloud, twice);
    ASSERT_EQ(ref.labels.size(), cloud.size()) << fc.name << ", " << what;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const float* p = &cloud.rec[4 * i];
      const bool finite = std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
      ASSERT_LE(ref.labels[i], 1) << fc.name << ", " << what << ", point " << i;
      if (!finite) ASSERT_EQ(ref.labels[i], gf::kNonGround) << fc.name << ", point " << i;
    }
    if (twice) {
      std::printf("[ info ] %s, %s: %zu allocations on the second scan (portable)\n", fc.name,
                  what.c_str(), ref.allocations_after_first);
      if (fc.allocation_free) {
        EXPECT_EQ(ref.allocations_after_first, 0u) << fc.name << " at portable, " << what;
      }
    }
    for (simd::Level level : levels()) {
      if (level == simd::Level::kPortable) continue;
      const ScanRun r = runAt(fc, level, cloud, twice);
      EXPECT_EQ(differences(ref.labels, r.labels), 0u)
          << fc.name << " at " << simd::levelName(level) << " vs portable, " << what;
      if (twice && r.allocations_after_first != 0) {
        std::printf("[ info ] %s, %s: %zu allocations on the second scan (%s)\n", fc.name,
                    what.c_str(), r.allocations_after_first, simd::levelName(level));
      }
      if (twice && fc.allocation_free) {
        EXPECT_EQ(r.allocations_after_first, 0u)
            << fc.name << " at " << simd::levelName(level) << ", " << what;
      }
    }
  }
}

std::size_t groundCount(const std::vector<std::uint8_t>& labels) {
  std::size_t n = 0;
  for (std::uint8_t l : labels) n += l == gf::kGround;
  return n;
}

}  // namespace

// ------------------------------------------------------------------ GF_SIMD and the levels

TEST(SimdLevels, NamesParseBothWaysAndPortableAlwaysRuns) {
  for (simd::Level l : {simd::Level::kPortable, simd::Level::kSse, simd::Level::kNeon,
                        simd::Level::kAvx2, simd::Level::kAvx512}) {
    simd::Level back;
    ASSERT_TRUE(simd::parseLevel(simd::levelName(l), &back)) << simd::levelName(l);
    EXPECT_EQ(back, l);
  }
  simd::Level l;
  EXPECT_TRUE(simd::parseLevel("AVX2", &l));
  EXPECT_EQ(l, simd::Level::kAvx2);
  EXPECT_FALSE(simd::parseLevel("avx", &l));
  EXPECT_FALSE(simd::parseLevel("", &l));
  EXPECT_TRUE(simd::supported(simd::Level::kPortable));
  EXPECT_TRUE(simd::supported(simd::best()));
#if defined(__x86_64__)
  EXPECT_TRUE(simd::supported(simd::Level::kSse));
  EXPECT_FALSE(simd::supported(simd::Level::kNeon));
#elif defined(__aarch64__)
  EXPECT_TRUE(simd::supported(simd::Level::kNeon));
  EXPECT_EQ(simd::best(), simd::Level::kNeon);
  EXPECT_FALSE(simd::supported(simd::Level::kSse));
  EXPECT_FALSE(simd::supported(simd::Level::kAvx2));
#endif
}

TEST(SimdLevels, AllowsFollowsTheLevelInForce) {
  for (simd::Level level : levels()) {
    simd::ScopedLevel scoped(level);
    ASSERT_TRUE(scoped.ok());
    EXPECT_EQ(simd::active(), level);
    EXPECT_TRUE(simd::allows(simd::Level::kPortable));
    EXPECT_TRUE(simd::allows(level));
    // neon and the x86 levels never allow each other
    if (level == simd::Level::kNeon) {
      EXPECT_FALSE(simd::allows(simd::Level::kSse));
      EXPECT_FALSE(simd::allows(simd::Level::kAvx2));
    } else {
      EXPECT_FALSE(simd::allows(simd::Level::kNeon));
    }
    if (level == simd::Level::kPortable) EXPECT_FALSE(simd::allows(simd::Level::kSse));
    if (level == simd::Level::kAvx2) EXPECT_FALSE(simd::allows(simd::Level::kAvx512));
    EXPECT_NE(simd::describe().find(std::string("SIMD ") + simd::levelName(level)),
              std::string::npos)
        << simd::describe();
  }
  // A level the CPU cannot run is refused and changes nothing.
  const simd::Level before = simd::active();
  for (simd::Level l :
       {simd::Level::kSse, simd::Level::kNeon, simd::Level::kAvx2, simd::Level::kAvx512}) {
    if (simd::supported(l)) continue;
    simd::ScopedLevel scoped(l);
    EXPECT_FALSE(scoped.ok()) << simd::levelName(l);
    EXPECT_EQ(simd::active(), before);
  }
}

TEST(SimdLevels, ResolveFallsBackToBestWithAReason) {
  std::string msg = "stale";
  EXPECT_EQ(simd::resolveLevel(nullptr, &msg), simd::best());
  EXPECT_TRUE(msg.empty());
  EXPECT_EQ(simd::resolveLevel("", &msg), simd::best());
  EXPECT_TRUE(msg.empty());
  EXPECT_EQ(simd::resolveLevel("Portable", &msg), simd::Level::kPortable);
  EXPECT_TRUE(msg.empty());
  EXPECT_EQ(simd::resolveLevel("avx9000", &msg), simd::best());
  EXPECT_NE(msg.find("GF_SIMD=avx9000 is not a SIMD level"), std::string::npos) << msg;
  EXPECT_NE(msg.find(std::string("using ") + simd::levelName(simd::best())), std::string::npos);
  for (simd::Level l :
       {simd::Level::kSse, simd::Level::kNeon, simd::Level::kAvx2, simd::Level::kAvx512}) {
    if (simd::supported(l)) {
      EXPECT_EQ(simd::resolveLevel(simd::levelName(l), &msg), l);
      EXPECT_TRUE(msg.empty()) << msg;
    } else {
      EXPECT_EQ(simd::resolveLevel(simd::levelName(l), &msg), simd::best());
      EXPECT_NE(msg.find("cannot run it"), std::string::npos) << msg;
    }
  }
}

// The public build-info call (logged by the nodelets) follows the level in force.
TEST(SimdLevels, BuildInfoNamesTheLevelInForce) {
  for (simd::Level level : {simd::Level::kPortable, simd::best()}) {
    simd::ScopedLevel scoped(level);
    ASSERT_TRUE(scoped.ok());
    const gf::BuildInfo info = gf::buildInfo();
    EXPECT_EQ(info.simd_level, simd::levelName(level));
    EXPECT_EQ(info.simd_best, simd::levelName(simd::best()));
    EXPECT_EQ(info.summary.find(simd::describe()), 0u) << info.summary;
    EXPECT_FALSE(info.compiler.empty());
    EXPECT_NE(info.summary.find(info.compiler), std::string::npos) << info.summary;
    // Not probed: the GPU is not asked; the line says whether CUDA is built.
    EXPECT_FALSE(info.cuda_probed);
    EXPECT_FALSE(info.cuda_available);
    EXPECT_NE(info.summary.find(info.cuda_built ? "CUDA built" : "CUDA not built"),
              std::string::npos)
        << info.summary;
  }
  // Probed: without the CUDA backend in the build the GPU is never available; the note says why.
  const gf::BuildInfo probed = gf::buildInfo(true);
  EXPECT_TRUE(probed.cuda_probed);
  if (!probed.cuda_built) EXPECT_FALSE(probed.cuda_available);
  EXPECT_EQ(probed.cuda_note.empty(), probed.cuda_available) << probed.cuda_note;
  EXPECT_NE(probed.summary.find(probed.cuda_available ? "CUDA yes" : "CUDA no ("),
            std::string::npos)
      << probed.summary;
}

// The child side of EnvironmentIsReadOncePerProcess: prints what GF_SIMD gave this process.
TEST(SimdLevelsChild, Report) {
  if (std::getenv("GF_SIMD_TEST_CHILD") == nullptr) {
    GTEST_SKIP() << "runs only as the child of SimdLevels.EnvironmentIsReadOncePerProcess";
  }
  std::printf("ACTIVE=%s\nDESCRIBE=%s\n", simd::levelName(simd::active()),
              simd::describe().c_str());
}

// GF_SIMD through a real process start: a level, a bad name and an unsupported level.
// GF_TEST_LAUNCHER runs the child (scripts/check_arm64.sh: qemu-aarch64).
TEST(SimdLevels, EnvironmentIsReadOncePerProcess) {
  char self[4096];
  const ssize_t len = readlink("/proc/self/exe", self, sizeof(self) - 1);
  ASSERT_GT(len, 0);
  self[len] = '\0';
  const char* launcher = std::getenv("GF_TEST_LAUNCHER");
  auto child = [&](const std::string& value) {
    const std::string cmd = "GF_SIMD_TEST_CHILD=1 GF_SIMD='" + value + "' " +
                            (launcher ? std::string(launcher) + " " : std::string()) + self +
                            " --gtest_filter=SimdLevelsChild.Report 2>&1";
    std::string out;
    if (FILE* p = popen(cmd.c_str(), "r")) {
      char buf[512];
      while (std::fgets(buf, sizeof(buf), p)) out += buf;
      EXPECT_EQ(pclose(p), 0) << cmd << "\n" << out;
    }
    return out;
  };
  const std::string best = std::string("ACTIVE=") + simd::levelName(simd::best());
  std::string out = child("portable");
  EXPECT_NE(out.find("ACTIVE=portable\n"), std::string::npos) << out;
  EXPECT_NE(out.find("GF_SIMD=portable)"), std::string::npos) << out;  // describe() names it
  out = child("fastest");
  EXPECT_NE(out.find(best + "\n"), std::string::npos) << out;
  EXPECT_NE(out.find("GF_SIMD=fastest is not a SIMD level"), std::string::npos) << out;
  for (simd::Level l : {simd::Level::kNeon, simd::Level::kAvx512}) {
    if (simd::supported(l)) continue;
    out = child(simd::levelName(l));
    EXPECT_NE(out.find(best + "\n"), std::string::npos) << out;
    EXPECT_NE(out.find("cannot run it"), std::string::npos) << out;
  }
}

// ------------------------------------------------------------------ filters at every level

TEST(SimdLevels, RealScanSameLabelsAtEveryLevel) {
  std::string source;
  const Cloud& scan = realScan(&source);
  ASSERT_GT(scan.size(), 50000u) << source;
  std::printf("[ info ] %s, %zu points; levels:", source.c_str(), scan.size());
  for (simd::Level l : levels()) std::printf(" %s", simd::levelName(l));
  std::printf("\n");
  expectSameAtEveryLevel(scan, source);
  // The scan is a street: plenty of ground for every filter (a filter that labels nothing
  // ground would pass the comparison above). The generated scene (no data) rolls: one global
  // plane (voxel_one_plane) keeps only part of it, as in FiveMillionPointsAtEveryLevel.
  const bool generated = source.rfind("generated", 0) == 0;
  for (const FilterCase& fc : filterCases()) {
    const ScanRun r = runAt(fc, simd::best(), scan, false);
    const bool one_plane = std::string(fc.name) == "voxel_one_plane";
    EXPECT_GT(groundCount(r.labels), scan.size() / (generated && one_plane ? 4 : 3))
        << fc.name << ", " << source;
  }
}

TEST(SimdLevels, FewerPointsThanKAtEveryLevel) {
  for (std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{2}, std::size_t{5},
                        std::size_t{63}, std::size_t{64}}) {
    Cloud c;
    for (std::size_t i = 0; i < n; ++i) {
      c.add(0.1f * static_cast<float>(i % 8), 0.1f * static_cast<float>(i / 8),
            0.01f * static_cast<float>(i % 3));
    }
    expectSameAtEveryLevel(c, std::to_string(n) + " points");
  }
}

TEST(SimdLevels, AllPointsIdenticalAtEveryLevel) {
  for (std::size_t n : {std::size_t{100}, std::size_t{100000}}) {
    Cloud c;
    for (std::size_t i = 0; i < n; ++i) c.add(3.f, -2.f, -1.7f);
    expectSameAtEveryLevel(c, std::to_string(n) + " identical points");
  }
}

TEST(SimdLevels, NanAndInfMixedInAtEveryLevel) {
  Cloud c = realScan(nullptr);
  // one coordinate of a point bad, in every lane and kind: NaN, +Inf, -Inf
  const float bad[] = {kNaN, kInf, -kInf};
  std::size_t invalid = 0;
  for (std::size_t i = 0; i < c.size(); i += 7) {
    c.rec[4 * i + (i / 7) % 3] = bad[(i / 21) % 3];
    ++invalid;
  }
  for (std::size_t i = 3; i < c.size(); i += 1001) {  // whole points NaN
    c.rec[4 * i] = c.rec[4 * i + 1] = c.rec[4 * i + 2] = kNaN;
    ++invalid;
  }
  ASSERT_GT(invalid, c.size() / 8);
  expectSameAtEveryLevel(c, "NaN/Inf mixed in");
  // and a cloud of nothing but non-finite points
  Cloud none;
  for (int i = 0; i < 1000; ++i) none.add(bad[i % 3], 1.f, bad[(i + 1) % 3]);
  expectSameAtEveryLevel(none, "only NaN/Inf");
}

// 5 M points: the voxel filter (defaults, airborne preset) twice at every level (no allocation on
// the second scan). Smaller clouds where one scan of 5 M took several seconds a level on the
// 2-core development VM: one global plane on 1 M, the normal method (each case) on 250 k (two KITTI
// frames; 1 M took 7-24 s a scan there). Prints each level's time for two scans.
TEST(SimdLevels, FiveMillionPointsAtEveryLevel) {
  const Cloud big = largeTerrain(5000000), million = largeTerrain(1000000),
              quarter = largeTerrain(250000);
  ASSERT_EQ(big.size(), 5000000u);
  for (const FilterCase& fc : filterCases()) {
    const std::string name = fc.name;
    const Cloud& cloud =
        std::string(fc.method) == "normal" ? quarter : (name == "voxel_one_plane" ? million : big);
    ScanRun ref;
    for (simd::Level level : levels()) {
      const auto t0 = std::chrono::steady_clock::now();
      const ScanRun r = runAt(fc, level, cloud, true);
      std::printf(
          "[ info ] %s, %zu points, %s: %.0f ms for two scans, %zu allocations on the "
          "second\n",
          fc.name, cloud.size(), simd::levelName(level),
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count(),
          r.allocations_after_first);
      if (fc.allocation_free) EXPECT_EQ(r.allocations_after_first, 0u) << fc.name;
      if (level == simd::Level::kPortable) {
        ref = r;
        // rolling terrain: one global plane (voxel_one_plane) keeps only part of it
        EXPECT_GT(groundCount(ref.labels), cloud.size() / 4) << fc.name;
      } else {
        EXPECT_EQ(differences(ref.labels, r.labels), 0u)
            << fc.name << " at " << simd::levelName(level) << ", " << cloud.size() << " points";
      }
    }
  }
}

// The grid keys of the column order and the tile sort: the AVX2 path (four points at a time,
// a group with a cell at or beyond 2^31 left to the scalar code) gives the portable keys, on
// points at the grid's origin, just below and above cell edges, far out, at 2^31 and beyond,
// and for every tail length.
TEST(CellKeys, EveryPathGivesThePortableKeys) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-80.f, 80.f);
  std::vector<float> xyz;
  for (int i = 0; i < 4000; ++i) xyz.insert(xyz.end(), {u(rng), u(rng), u(rng)});
  const double min_x = -80.0, min_y = -80.0;
  for (double cell : {0.1, 1.0, 0.3}) {  // points on and around cell edges
    for (int k = 0; k < 40; ++k) {
      const float e = static_cast<float>(min_x + k * cell);
      xyz.insert(xyz.end(), {e, std::nextafter(e, 1e9f), 0.f});
      xyz.insert(xyz.end(), {std::nextafter(e, -1e9f), e, 0.f});
    }
  }
  xyz.insert(xyz.end(), {-80.f, -80.f, 0.f, 3.0e8f, 5.0f, 0.f, 2.0e8f, 2.1e8f, 1.f});
  xyz.insert(xyz.end(), {5.0e8f, -80.f, 0.f, 1.f, 4.5e8f, 2.f, -100.f, -95.f, 0.f});
  const std::size_t n = xyz.size() / 3;
  for (double inv : {10.0, 1.0 / 0.3, 1.0}) {
    for (std::size_t b : {std::size_t{0}, std::size_t{1}, std::size_t{3}}) {
      for (std::size_t e : {n, n - 1, n - 2, n - 3, b + 5}) {
        std::vector<std::uint64_t> want(n, 7), got(n, 7), want_t(n, 7), got_t(n, 7);
        {
          simd::ScopedLevel portable(simd::Level::kPortable);
          ASSERT_TRUE(portable.ok());
          gf::normal::columnKeysOf(xyz.data(), b, e, min_x, min_y, inv, want.data());
          gf::normal::tileKeysOf(xyz.data(), b, e, min_x, min_y, inv, 31, want_t.data());
        }
        for (std::size_t i = b; i < e; ++i) {  // the definition
          const std::uint32_t cx = gf::normal::cellIndex(xyz[3 * i], min_x, inv);
          const std::uint32_t cy = gf::normal::cellIndex(xyz[3 * i + 1], min_y, inv);
          ASSERT_EQ(want[i], gf::normal::columnKey(cx, cy)) << i;
          ASSERT_EQ(want_t[i], (std::uint64_t{cx} << 31) | cy) << i;
        }
        for (simd::Level level : {simd::Level::kAvx2, simd::Level::kAvx512}) {
          if (!simd::supported(level)) continue;
          simd::ScopedLevel scoped(level);
          gf::normal::columnKeysOf(xyz.data(), b, e, min_x, min_y, inv, got.data());
          gf::normal::tileKeysOf(xyz.data(), b, e, min_x, min_y, inv, 31, got_t.data());
          EXPECT_EQ(got, want) << simd::levelName(level) << " b " << b << " e " << e;
          EXPECT_EQ(got_t, want_t) << simd::levelName(level) << " b " << b << " e " << e;
        }
      }
    }
  }
}
