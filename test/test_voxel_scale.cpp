// Voxel filter at scale and the voxelizer's passes: identical labels for any thread count on
// large clouds, no allocation after the first scan, the AVX2 and threaded passes give the serial
// SSE2 grid byte for byte.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <new>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "gf_test_alloc_counter.h"  // allocationCount()
#include "gf_test_data.h"
#include "gf_test_scenes.h"
#include "gf_test_voxel.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/voxel_ground_filter.h"
#include "voxel/avx2_passes.h"
#include "voxel/voxelize.h"

namespace gf = ground_filter;

namespace {

using Cloud = gf_test::TruthCloud;
// The shared scenes and voxel helpers (gf_test_scenes.h, gf_test_voxel.h).
using namespace gf_test;  // NOLINT(build/namespaces)

}  // namespace

namespace {

// Above the filter's parallel threshold (150 k valid points, src/core/voxel/voxel_grid.h), with
// NaN points. `wide`: 600 m across with a 15 m pole, so a voxel key needs more than 32 bits (key
// and point index still share one sort word). `huge`: two points 9 km away on every axis, so key
// and point index no longer fit one word (the sort moves them separately).
Cloud largeScene(bool wide, bool huge = false) {
  std::mt19937 rng(wide ? 21 : 20);
  Cloud c;
  auto ground = [](float x, float y) { return 0.03f * x - 0.01f * y; };
  addSurface(&c, -12, 12, -12, 12, 0.04f, ground, 0.02f, &rng);
  if (wide) {
    addSurface(&c, -300, 300, -300, 300, 1.4f, ground, 0.02f, &rng);
    for (float z = 0.f; z < 15.f; z += 0.05f) c.add(250.f, 250.f, ground(250.f, 250.f) + z, false);
  }
  addBox(&c, -4.f, 5.f, 3.f, 2.f, ground(-4.f, 5.f), 2.f, 0.05f);
  addBox(&c, 6.f, -3.f, 1.f, 4.f, ground(6.f, -3.f), 1.f, 0.05f);
  if (huge) {
    c.add(-4500.f, -4500.f, -4500.f, false);
    c.add(4500.f, 4500.f, 4500.f, false);
  }
  for (std::size_t i = 0; i < c.size(); i += 97) {
    c.xyz[3 * i + (i % 3)] = std::numeric_limits<float>::quiet_NaN();
    c.truth[i] = 0;
  }
  return c;
}

// A survey-sized tile: 1.05 M points over 500 x 500 m on a slope (20 m of height), with boxes:
// 34-bit voxel keys, sorted top-down (kTopDownSortMinPoints) in buckets of a few hundred keys.
Cloud surveyTile() {
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> u(0.f, 500.f), noise(-0.02f, 0.02f);
  auto ground = [](float x, float y) { return 0.03f * x - 0.01f * y; };
  Cloud c;
  for (int i = 0; i < 1050000; ++i) {
    const float x = u(rng), y = u(rng);
    c.add(x, y, ground(x, y) + noise(rng), true);
  }
  for (float b = 50.f; b < 500.f; b += 75.f)
    addBox(&c, b, 480.f - b, 3.f, 3.f, ground(b, 480.f - b), 2.f, 0.1f);
  return c;
}

}  // namespace

TEST(VoxelGroundFilter, SameLabelsForAnyThreadCountOnLargeClouds) {
  for (bool wide : {false, true}) {
    const Cloud c = largeScene(wide);
    ASSERT_GT(c.size(), 200000u);
    gf::VoxelGroundFilterParams p = groundLevel();
    p.threads = 1;
    const auto ref = run(c, p);
    EXPECT_GT(agreement(ref, c.truth, 1), 0.9) << "wide " << wide;  // ground found
    EXPECT_GT(agreement(ref, c.truth, 0), 0.9) << "wide " << wide;  // boxes and NaN are not
    for (int threads : {2, 3, 4, 0}) {
      p.threads = threads;
      EXPECT_EQ(ref, run(c, p)) << "threads " << threads << ", wide " << wide;
    }
  }
  {  // the vegetation rule (its own parallel passes) on a large scene with bushes
    Cloud c = largeScene(false);
    std::mt19937 rng(22);
    std::vector<std::size_t> base;
    auto ground = [](float x, float y) { return 0.03f * x - 0.01f * y; };
    for (float x = -9.f; x < 10.f; x += 4.5f)
      addPorousBush(&c, x, -8.f, ground(x, -8.f), 0.7f, 0.8f, &rng, &base);
    gf::VoxelGroundFilterParams p = vegetationRule(true);
    p.threads = 1;
    const auto ref = run(c, p);
    EXPECT_LT(groundShare(ref, base), 0.1);  // the rule acts
    for (int threads : {2, 3, 4, 0}) {
      p.threads = threads;
      EXPECT_EQ(ref, run(c, p)) << "threads " << threads << ", vegetation rule";
    }
  }
  const Cloud c = largeScene(false, true);
  gf::VoxelGroundFilterParams p = groundLevel();
  p.threads = 1;
  const auto ref = run(c, p);
  EXPECT_GT(agreement(ref, c.truth, 1), 0.5);  // coarse cells (capped cell count), still ground
  for (int threads : {2, 3}) {
    p.threads = threads;
    EXPECT_EQ(ref, run(c, p)) << "threads " << threads << ", huge";
  }
}

TEST(VoxelGroundFilter, NoAllocationAfterTheFirstScanOfASize) {
  const Cloud large = largeScene(false), survey = surveyTile();  // survey: threaded sort, gather
  for (const Cloud* cloud : {&large, &survey}) {
    const Cloud& c = *cloud;
    for (int threads : {1, 2}) {
      for (bool veg : {false, true}) {
        gf::VoxelGroundFilterParams p = vegetationRule(veg);
        p.threads = threads;
        gf::VoxelGroundFilter f(p);
        std::vector<std::uint8_t> first;
        gf::FilterStats stats;
        f.filter(c.view(), &first, &stats);
        // "level" first; + "vegetation"; "line_walls" last (single scans); the survey tile's
        // 4 points a m2 get coarser voxels twice ("coarser_voxels")
        const std::size_t stages = (veg ? 9u : 8u) + (cloud == &survey ? 2u : 0u);
        ASSERT_EQ(stats.stage_ms.size(), stages);
        std::vector<std::uint8_t> labels(c.size(), 2);  // allocated before counting
        const std::size_t before = allocationCount().load();
        f.filter(c.view(), &labels, &stats);  // reused labels and stats
        f.filter(c.view(), &labels, nullptr);
        EXPECT_EQ(allocationCount().load() - before, 0u)
            << c.size() << " points, threads " << threads << ", veg " << veg;
        EXPECT_EQ(first, labels);
        EXPECT_EQ(stats.stage_ms.size(), stages);
      }
    }
  }
}

namespace {

// Everything build() leaves in a VoxelGrid (and the unsorted keys of prepare()), as bytes.
std::vector<std::vector<std::uint8_t>> gridBytes(
    const gf::CloudView& view, int threads, bool avx2, bool local_planes,
    std::size_t parallel_min_points = gf::voxel::kParallelSortMinPoints) {
  gf::voxel::Voxelizer vz;
  vz.setUseAvx2(avx2);
  vz.setParallelMinPoints(parallel_min_points);
  gf::voxel::VoxelGrid g;
  gf::voxel::CellGrid cells;
  gf::voxel::WorkerPool pool;
  gf::VoxelGroundFilterParams p = groundLevel();
  p.local_planes = local_planes;  // the flat list: flat seed candidates, or every flat voxel
  const std::size_t n = vz.prepare(view, p.voxel_size, threads, &pool, nullptr, &g);
  auto bytes = [](const auto& v, std::size_t count) {
    const auto* b = reinterpret_cast<const std::uint8_t*>(v.data());
    return std::vector<std::uint8_t>(b, b + count * sizeof(v[0]));
  };
  std::vector<std::vector<std::uint8_t>> out;
  const std::vector<std::uint64_t> dims = {n, g.nx, g.ny, g.nz};
  out.push_back(bytes(dims, 4));
  out.push_back(bytes(g.keys, g.keys.size()));
  cells.setup(p, g.nx, g.ny);
  vz.build(p, threads, &pool, &g, &cells);
  out.push_back(bytes(g.keys, g.keys.size()));
  out.push_back(bytes(g.sxyz, 3 * n));
  out.push_back(bytes(g.vx, g.vx.size()));
  out.push_back(bytes(g.vy, g.vy.size()));
  out.push_back(bytes(g.vz, g.vz.size()));
  out.push_back(bytes(g.vflags, g.vflags.size()));
  out.push_back(bytes(g.vstart, g.vstart.size()));
  out.push_back(bytes(g.flat, g.flat.size()));
  out.push_back(bytes(g.seeds, g.seeds.size()));
  out.push_back(bytes(g.col_key, g.col_key.size()));
  out.push_back(bytes(g.col_first, g.col_first.size()));
  out.push_back(bytes(g.vcell, g.vcell.size()));
  out.push_back(bytes(cells.used, cells.used.size()));
  return out;
}

}  // namespace

// The AVX2 passes (bounds, keys, centroids, flags and lists) give the SSE2 passes' grid bit for
// bit: every record layout they read, clouds with and without NaN points (NaNs inside blocks of
// eight), sizes that leave a scalar tail, and two threads (chunk bounds that are not multiples of
// eight).
TEST(Voxelizer, Avx2PassesGiveTheSse2Grid) {
  if (!gf::voxel::cpuHasAvx2()) GTEST_SKIP() << "this CPU or build has no AVX2";
  Cloud valid_large = largeScene(false);
  for (float& v : valid_large.xyz) v = std::isnan(v) ? 0.5f : v;
  Cloud with_nan = slopeWithBox(9);
  for (std::size_t i = 5; i < with_nan.size(); i += 89) with_nan.xyz[3 * i + (i % 3)] = NAN;
  with_nan.xyz[3 * 7 + 1] = INFINITY;
  with_nan.xyz[3 * 11] = -INFINITY;
  Cloud small = slopeWithBox(8);
  for (Cloud* c : {&valid_large, &with_nan, &small}) {
    if (c->size() % 8 == 0) c->add(0.5f, 0.5f, 0.5f, false);  // a scalar tail
  }
  struct Case {
    const Cloud* cloud;
    int threads;
  };
  const Case cases[] = {{&small, 1}, {&with_nan, 1}, {&valid_large, 2}, {&valid_large, 1}};
  // {stride, x offset}: 16-byte records read in place (every one / all but the last), packed
  // x y z (12 bytes), and the aligned copy of wider records.
  const std::size_t layouts[4][2] = {{16, 0}, {16, 4}, {12, 0}, {24, 4}};
  for (const Case& cs : cases) {
    const Cloud& c = *cs.cloud;
    for (const auto& l : layouts) {
      const std::size_t stride = l[0], xo = l[1];
      std::vector<std::uint8_t> buf(c.size() * stride, 0xFF);  // the bytes around x y z: NaN
      for (std::size_t i = 0; i < c.size(); ++i) {
        std::memcpy(&buf[i * stride + xo], &c.xyz[3 * i], 12);
      }
      const gf::CloudView view(buf.data(), c.size(), stride, xo, xo + 4, xo + 8);
      for (bool local : {true, false}) {
        const auto sse2 = gridBytes(view, cs.threads, false, local);
        const auto avx2 = gridBytes(view, cs.threads, true, local);
        ASSERT_EQ(sse2.size(), avx2.size());
        for (std::size_t k = 0; k < sse2.size(); ++k) {
          EXPECT_TRUE(sse2[k] == avx2[k])
              << "array " << k << ", " << c.size() << " points, stride " << stride << ", x at "
              << xo << ", threads " << cs.threads << ", local planes " << local;
        }
      }
    }
  }
}

// The sort and the gather on several threads (from setParallelMinPoints() points on) give the
// serial grid bit for bit: the LSD sort's blocks and the gather's ranges (lowered threshold; NaN
// points, 16-byte records read in place and wider ones copied, keys too wide to share a word
// with the slot), and the top-down sort's bucket ranges on a survey-sized tile.
TEST(Voxelizer, ThreadsGiveTheSerialGrid) {
  Cloud with_nan = largeScene(true);
  Cloud valid = largeScene(false);
  for (float& v : valid.xyz) v = std::isnan(v) ? 0.5f : v;
  const Cloud huge = largeScene(false, true);  // 51-bit keys: key and slot words apart
  const Cloud survey = surveyTile();
  struct Case {
    const Cloud* cloud;
    std::size_t stride;
    std::size_t parallel_min;
  };
  const Case cases[] = {{&with_nan, 16, 1},
                        {&valid, 16, 1},
                        {&valid, 32, 1},
                        {&huge, 16, 1},
                        {&survey, 12, gf::voxel::kParallelSortMinPoints}};
  for (const Case& cs : cases) {
    const Cloud& c = *cs.cloud;
    std::vector<std::uint8_t> buf(c.size() * cs.stride, 0);
    for (std::size_t i = 0; i < c.size(); ++i) std::memcpy(&buf[i * cs.stride], &c.xyz[3 * i], 12);
    const gf::CloudView view(buf.data(), c.size(), cs.stride, 0, 4, 8);
    ASSERT_GE(c.size(), cs.parallel_min);
    for (bool local : {true, false}) {
      const auto serial = gridBytes(view, 1, gf::voxel::cpuHasAvx2(), local, cs.parallel_min);
      for (int threads : {2, 3}) {
        const auto threaded =
            gridBytes(view, threads, gf::voxel::cpuHasAvx2(), local, cs.parallel_min);
        ASSERT_EQ(serial.size(), threaded.size());
        for (std::size_t k = 0; k < serial.size(); ++k) {
          EXPECT_TRUE(serial[k] == threaded[k])
              << "array " << k << ", " << c.size() << " points, stride " << cs.stride
              << ", threads " << threads << ", local planes " << local;
        }
      }
    }
  }
  // The whole filter on the survey tile.
  gf::VoxelGroundFilterParams p = groundLevel();
  p.threads = 1;
  const auto ref = run(survey, p);
  EXPECT_GT(agreement(ref, survey.truth, 1), 0.9);
  for (int threads : {2, 3}) {
    p.threads = threads;
    EXPECT_EQ(ref, run(survey, p)) << "threads " << threads << ", survey tile";
  }
}
