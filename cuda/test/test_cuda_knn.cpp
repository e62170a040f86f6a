// GPU tests of CudaKnn against a brute-force search (run on a machine with a CUDA GPU).
// Distances use the same float arithmetic on both sides and rows are ordered by (distance, index),
// so rows must match exactly, ties included.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "brute_force_knn.h"
#include "gpu_test.h"
#include "ground_filter/cuda_knn.h"
#include "knn_tuning.h"

using ground_filter::CudaError;
using ground_filter::CudaKnn;
using ground_filter::CudaKnnOptions;
using ground_filter::CudaKnnQueryStats;
using ground_filter::CudaKnnTuning;
using ground_filter::CudaKnnTuningAccess;

namespace {

struct Lists {
  std::vector<std::int32_t> idx;
  std::vector<float> d2;
};

Lists run(CudaKnn& knn, const std::vector<float>& xyz, int k) {
  const std::size_t n = xyz.size() / 3;
  Lists l;
  // Poisoned, so an unwritten entry cannot pass.
  l.idx.assign(n * k, -7);
  l.d2.assign(n * k, -1.f);
  knn.search(xyz.data(), n, k, l.idx.data(), l.d2.data());
  return l;
}

/// run() on a new CudaKnn with the experiment knobs `o`; with `stats`, the work counters are
/// collected (CudaKnnTuning::collect_stats) into it.
Lists runTuned(CudaKnnTuning o, const std::vector<float>& xyz, int k,
               CudaKnnQueryStats* stats = nullptr) {
  o.collect_stats = o.collect_stats || stats != nullptr;
  CudaKnn knn;
  CudaKnnTuningAccess::set(knn, o);
  Lists l = run(knn, xyz, k);
  if (stats) *stats = CudaKnnTuningAccess::stats(knn);
  return l;
}

/// Every row of `l` equals brute force; `sample` > 0 checks that many random rows only.
void expectExact(const std::vector<float>& xyz, int k, const Lists& l, std::size_t sample = 0,
                 unsigned seed = 1) {
  const std::size_t n = xyz.size() / 3;
  std::vector<std::size_t> queries;
  if (sample > 0 && sample < n) {
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<std::size_t> pick(0, n - 1);
    for (std::size_t i = 0; i < sample; ++i) queries.push_back(pick(rng));
    queries.push_back(0);
    queries.push_back(n - 1);
  }
  std::string first;
  const std::size_t bad =
      gf_test::compareRows(xyz.data(), n, k, l.idx.data(), l.d2.data(), queries, &first);
  EXPECT_EQ(bad, 0u) << "n = " << n << ", k = " << k << "; first mismatch: " << first;
}

std::vector<float> uniformCloud(std::size_t n, float sx, float sy, float sz, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> ux(-sx, sx), uy(-sy, sy), uz(-sz, sz);
  std::vector<float> xyz(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    xyz[3 * i] = ux(rng);
    xyz[3 * i + 1] = uy(rng);
    xyz[3 * i + 2] = uz(rng);
  }
  return xyz;
}

/// LiDAR-like: a noisy ground plane sampled densely near the origin and sparsely far away, plus
/// gaussian blobs (objects) and a few isolated outliers.
std::vector<float> lidarLikeCloud(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u01(0.f, 1.f), ang(0.f, 6.2831853f);
  std::normal_distribution<float> noise(0.f, 0.02f), blob(0.f, 0.4f);
  std::vector<float> xyz;
  xyz.reserve(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const float kind = u01(rng);
    if (kind < 0.7f) {  // ground: radius ~ r^2 density falloff
      const float r = 2.f + 78.f * u01(rng) * u01(rng), a = ang(rng);
      xyz.insert(xyz.end(), {r * std::cos(a), r * std::sin(a), -1.73f + noise(rng)});
    } else if (kind < 0.995f) {  // objects around 10 blob centres
      const int c = static_cast<int>(u01(rng) * 10.f);
      const float cx = -40.f + 8.f * c, cy = 15.f - 3.f * c;
      xyz.insert(xyz.end(), {cx + blob(rng), cy + blob(rng), blob(rng)});
    } else {  // isolated outliers
      xyz.insert(xyz.end(),
                 {-100.f + 200.f * u01(rng), -100.f + 200.f * u01(rng), -5.f + 30.f * u01(rng)});
    }
  }
  return xyz;
}

using CudaKnnTest = gf_test::GpuTest;

TEST_F(CudaKnnTest, DeviceReportsItself) {
  CudaKnn knn;
  EXPECT_FALSE(knn.deviceName().empty());
  std::string why = "untouched";
  EXPECT_TRUE(CudaKnn::deviceAvailable(&why));
  EXPECT_TRUE(why.empty());
  EXPECT_FALSE(CudaKnn::deviceAvailable(&why, 1000));
  EXPECT_NE(why.find("cudaErrorInvalidDevice"), std::string::npos) << why;
}

TEST_F(CudaKnnTest, RandomCloudsMatchBruteForce) {
  CudaKnn knn;
  const std::size_t sizes[] = {1, 2, 7, 33, 100, 1000, 20000};
  const int ks[] = {1, 3, 8, 32, 33, 50, 64};
  unsigned seed = 10;
  for (std::size_t n : sizes) {
    for (int k : ks) {
      const auto box = uniformCloud(n, 10.f, 10.f, 10.f, ++seed);
      expectExact(box, k, run(knn, box, k));
      const auto flat = uniformCloud(n, 50.f, 30.f, 0.05f, ++seed);  // a noisy plane (2-D)
      expectExact(flat, k, run(knn, flat, k));
    }
  }
}

TEST_F(CudaKnnTest, LidarLikeCloudMatchesBruteForce) {
  CudaKnn knn;
  const auto xyz = lidarLikeCloud(60000, 3);
  for (int k : {10, 50, 64}) expectExact(xyz, k, run(knn, xyz, k));
}

TEST_F(CudaKnnTest, KittiFrameMatchesBruteForce) {
  const auto xyz = gf_test::readKittiBin(std::string(GF_DATA_DIR) + "/000000.bin");
  ASSERT_GT(xyz.size(), 3u * 100000) << "missing " << GF_DATA_DIR << "/000000.bin";
  CudaKnn knn;
  const Lists l = run(knn, xyz, 50);
  expectExact(xyz, 50, l, 4000, 7);
  // Rows are sorted and every point finds itself or a duplicate at distance 0.
  const std::size_t n = xyz.size() / 3;
  std::size_t unsorted = 0, no_self = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (l.d2[i * 50] != 0.f) ++no_self;
    for (int j = 1; j < 50; ++j) unsorted += l.d2[i * 50 + j] < l.d2[i * 50 + j - 1];
  }
  EXPECT_EQ(unsorted, 0u);
  EXPECT_EQ(no_self, 0u);
  const auto& t = knn.lastTimings();
  std::printf(
      "[ KITTI    ] n = %zu, K = 50 (first call): upload %.2f ms, grid %.2f ms (%d levels, "
      "finest 2^%d), query + download %.2f ms, total %.2f ms\n",
      n, t.upload_ms, t.grid_ms, t.levels, t.finest_bits, t.query_ms, t.total_ms);
}

TEST_F(CudaKnnTest, DuplicatesMatchBruteForce) {
  CudaKnn knn;
  // Each of 3000 distinct points 1..12 times, plus one point repeated 500 times (> K).
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> rep(1, 12);
  const auto base = uniformCloud(3000, 5.f, 5.f, 1.f, 6);
  std::vector<std::size_t> order;  // point ids of the duplicated cloud, shuffled
  for (std::size_t i = 0; i < 3000; ++i) order.insert(order.end(), rep(rng), i);
  order.insert(order.end(), 500, 3000);
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<float> xyz;
  for (std::size_t id : order) {
    if (id == 3000)
      xyz.insert(xyz.end(), {1.f, 2.f, 0.5f});
    else
      xyz.insert(xyz.end(), base.begin() + 3 * id, base.begin() + 3 * id + 3);
  }
  for (int k : {1, 16, 50, 64}) expectExact(xyz, k, run(knn, xyz, k));
}

TEST_F(CudaKnnTest, CloudSmallerThanKIsPadded) {
  CudaKnn knn;
  const auto xyz = uniformCloud(5, 1.f, 1.f, 1.f, 8);
  const Lists l = run(knn, xyz, 16);
  expectExact(xyz, 16, l);
  for (std::size_t i = 0; i < 5; ++i) {
    for (int j = 0; j < 16; ++j) {
      if (j < 5) {
        EXPECT_GE(l.idx[i * 16 + j], 0);
        EXPECT_TRUE(std::isfinite(l.d2[i * 16 + j]));
      } else {
        EXPECT_EQ(l.idx[i * 16 + j], -1);
        EXPECT_EQ(l.d2[i * 16 + j], std::numeric_limits<float>::infinity());
      }
    }
  }
  // One point, K = 64.
  const std::vector<float> one = {3.f, -2.f, 1.f};
  const Lists l1 = run(knn, one, 64);
  EXPECT_EQ(l1.idx[0], 0);
  EXPECT_EQ(l1.d2[0], 0.f);
  EXPECT_EQ(l1.idx[63], -1);
}

TEST_F(CudaKnnTest, EmptyCloudWritesNothing) {
  CudaKnn knn;
  std::int32_t idx = 123;
  float d2 = 4.f;
  EXPECT_NO_THROW(knn.search(nullptr, 0, 50, &idx, &d2));
  EXPECT_EQ(idx, 123);
  EXPECT_EQ(d2, 4.f);
}

TEST_F(CudaKnnTest, AllPointsInOneTinyCell) {
  CudaKnn knn;
  // 20000 points inside a 1 mm cube far from the origin: the grid refines down to it.
  auto xyz = uniformCloud(20000, 0.0005f, 0.0005f, 0.0005f, 9);
  for (std::size_t i = 0; i < xyz.size(); i += 3) {
    xyz[i] += 50.f;
    xyz[i + 1] -= 20.f;
    xyz[i + 2] += 3.f;
  }
  expectExact(xyz, 50, run(knn, xyz, 50), 3000);
  // 3000 copies of one point: every row is the 50 lowest indices at distance 0.
  std::vector<float> same;
  for (int i = 0; i < 3000; ++i) same.insert(same.end(), {7.f, 7.f, 7.f});
  const Lists l = run(knn, same, 50);
  expectExact(same, 50, l, 300);
  EXPECT_EQ(l.idx[2999 * 50 + 49], 49);
}

TEST_F(CudaKnnTest, KilometreWideCloud) {
  CudaKnn knn;
  // Two dense 1 m clusters 5 km apart, a 40-point cluster at 10 km and sparse points in between.
  std::vector<float> xyz;
  const auto a = uniformCloud(20000, 0.5f, 0.5f, 0.5f, 11);
  const auto b = uniformCloud(20000, 0.5f, 0.5f, 0.5f, 12);
  const auto c = uniformCloud(40, 0.2f, 0.2f, 0.2f, 13);
  const auto s = uniformCloud(2000, 5000.f, 5000.f, 100.f, 14);
  xyz.insert(xyz.end(), a.begin(), a.end());
  for (std::size_t i = 0; i < b.size(); i += 3)
    xyz.insert(xyz.end(), {b[i] + 5000.f, b[i + 1], b[i + 2]});
  for (std::size_t i = 0; i < c.size(); i += 3) {
    xyz.insert(xyz.end(), {c[i] + 10000.f, c[i + 1] - 3000.f, c[i + 2]});
  }
  xyz.insert(xyz.end(), s.begin(), s.end());
  const Lists l = run(knn, xyz, 50);
  expectExact(xyz, 50, l, 4000);
  // The 40-point cluster's rows reach out to other points: check them all.
  std::vector<std::size_t> far_rows;
  for (std::size_t i = 40000; i < 40040; ++i) far_rows.push_back(i);
  std::string first;
  EXPECT_EQ(gf_test::compareRows(xyz.data(), xyz.size() / 3, 50, l.idx.data(), l.d2.data(),
                                 far_rows, &first),
            0u)
      << first;
  EXPECT_LT(knn.deviceBytes(), std::size_t(1) << 30);  // memory follows points, not extent
}

TEST_F(CudaKnnTest, FiveMillionPoints) {
  CudaKnn knn;
  // 5 M points: the KITTI frame tiled with x/y offsets when present, else a LiDAR-like cloud.
  auto frame = gf_test::readKittiBin(std::string(GF_DATA_DIR) + "/000000.bin");
  std::vector<float> xyz;
  const std::size_t target = 5000000;
  xyz.reserve(3 * target);
  if (frame.empty()) frame = lidarLikeCloud(124000, 21);
  const std::size_t fn = frame.size() / 3;
  for (int t = 0; xyz.size() < 3 * target; ++t) {
    const float ox = 160.f * (t % 7), oy = 160.f * (t / 7);
    for (std::size_t i = 0; i < fn && xyz.size() < 3 * target; ++i) {
      xyz.insert(xyz.end(), {frame[3 * i] + ox, frame[3 * i + 1] + oy, frame[3 * i + 2]});
    }
  }
  const Lists l = run(knn, xyz, 50);
  expectExact(xyz, 50, l, 1500, 17);
  std::size_t unwritten = 0;
  for (std::size_t i = 0; i < l.idx.size(); ++i) unwritten += l.idx[i] < 0 || l.d2[i] < 0.f;
  EXPECT_EQ(unwritten, 0u);
  const auto& t = knn.lastTimings();
  std::printf(
      "[ 5M       ] n = %zu, K = 50 (first call): upload %.2f ms, grid %.2f ms (%d "
      "levels), query + download %.2f ms, total %.2f ms, device %.0f MiB\n",
      xyz.size() / 3, t.upload_ms, t.grid_ms, t.levels, t.query_ms, t.total_ms,
      knn.deviceBytes() / 1048576.0);
}

TEST_F(CudaKnnTest, NonFiniteInputIsRejectedAndInstanceStaysUsable) {
  CudaKnn knn;
  auto xyz = uniformCloud(1000, 1.f, 1.f, 1.f, 15);
  std::vector<std::int32_t> idx(1000 * 8);
  std::vector<float> d2(1000 * 8);
  xyz[3 * 500 + 1] = std::numeric_limits<float>::quiet_NaN();
  try {
    knn.search(xyz.data(), 1000, 8, idx.data(), d2.data());
    FAIL() << "NaN accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("NaN/Inf"), std::string::npos) << e.what();
  }
  xyz[3 * 500 + 1] = std::numeric_limits<float>::infinity();
  EXPECT_THROW(knn.search(xyz.data(), 1000, 8, idx.data(), d2.data()), std::invalid_argument);
  xyz[3 * 500 + 1] = 0.25f;
  expectExact(xyz, 8, run(knn, xyz, 8));
}

TEST_F(CudaKnnTest, BadKIsRejected) {
  CudaKnn knn;
  const auto xyz = uniformCloud(100, 1.f, 1.f, 1.f, 16);
  std::vector<std::int32_t> idx(100 * 65);
  std::vector<float> d2(100 * 65);
  EXPECT_THROW(knn.search(xyz.data(), 100, 0, idx.data(), d2.data()), std::invalid_argument);
  EXPECT_THROW(knn.search(xyz.data(), 100, 65, idx.data(), d2.data()), std::invalid_argument);
}

TEST_F(CudaKnnTest, BuffersGrowOnlyAndResultsStayRight) {
  CudaKnn knn;
  const auto big = lidarLikeCloud(80000, 18), small = lidarLikeCloud(5000, 19);
  expectExact(big, 50, run(knn, big, 50), 2000);
  const std::size_t held = knn.deviceBytes();
  EXPECT_GT(held, 0u);
  expectExact(small, 50, run(knn, small, 50));
  EXPECT_EQ(knn.deviceBytes(), held);  // no reallocation for a smaller scan
  expectExact(big, 50, run(knn, big, 50), 2000);
  EXPECT_EQ(knn.deviceBytes(), held);
}

TEST_F(CudaKnnTest, OptionsChangeSpeedNeverLists) {
  const auto xyz = lidarLikeCloud(30000, 20);
  CudaKnn knn;
  const Lists a = run(knn, xyz, 40);
  expectExact(xyz, 40, a, 2000);
  // Without distances.
  std::vector<std::int32_t> idx(a.idx.size(), -7);
  knn.search(xyz.data(), xyz.size() / 3, 40, idx.data(), nullptr);
  EXPECT_EQ(idx, a.idx);
  // Cells in raster order, work counters on, other level choices.
  for (int mp : {0, 1, 4, 40, 1000}) {
    for (bool sorted : {false, true}) {
      CudaKnnTuning o;
      o.level_min_points = mp;
      o.sort_cells = sorted;
      CudaKnnQueryStats t;  // collects them
      const Lists c = runTuned(o, xyz, 40, &t);
      EXPECT_EQ(a.idx, c.idx) << "level_min_points = " << mp << ", sort_cells = " << sorted;
      EXPECT_EQ(a.d2, c.d2);
      EXPECT_GE(t.candidates_per_query, 40.0);
      EXPECT_GE(t.insertions_per_query, 40.0);
      EXPECT_LE(t.insertions_per_query, t.candidates_per_query);
      EXPECT_GE(t.shells_per_query, 1.0);
      EXPECT_GE(t.levels_per_query, 1.0);
      EXPECT_GE(t.max_query_cycles, t.mean_query_cycles);
    }
  }
  // Heavy queries split over 16 warps (outliers 100 m out), with any pipeline depth.
  for (int heavy : {0, 1, 100, 2000}) {
    for (int chunks : {1, 3}) {
      CudaKnnTuning o;
      o.heavy_candidates = heavy;
      o.download_chunks = chunks;
      const Lists c = runTuned(o, xyz, 40);
      EXPECT_EQ(a.idx, c.idx) << "heavy_candidates = " << heavy << ", " << chunks << " chunks";
      EXPECT_EQ(a.d2, c.d2);
    }
  }
  // Any depth of the query/download pipeline.
  for (int chunks : {1, 3, 16}) {
    CudaKnnTuning o;
    o.download_chunks = chunks;
    const Lists c = runTuned(o, xyz, 40);
    EXPECT_EQ(a.idx, c.idx) << chunks << " chunks";
    EXPECT_EQ(a.d2, c.d2);
  }
  // Deterministic: the same call twice gives the same bits.
  const Lists a2 = run(knn, xyz, 40);
  EXPECT_EQ(a.idx, a2.idx);
  EXPECT_EQ(a.d2, a2.d2);
}

TEST_F(CudaKnnTest, ListMergingDuplicateSkipAndHeavySplitMatchBruteForce) {
  // A ring of points around 4,000 copies of the origin (an Ouster's no-returns): queries on the
  // ring reach the origin's cell but not always the origin, so runs of identical points are
  // skipped at distances > 0; plus duplicates (1..12 copies) and a plain box.
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> ang(0.f, 6.2831853f), rad(0.6f, 3.f), zz(-0.3f, 0.3f);
  std::uniform_int_distribution<int> rep(1, 12);
  std::vector<float> ring;
  for (int i = 0; i < 6000; ++i) {
    if (i % 3 == 0) {
      ring.insert(ring.end(), {0.f, 0.f, 0.f});
      ring.insert(ring.end(), {0.f, 0.f, 0.f});
    }
    const float a = ang(rng), r = rad(rng), z = zz(rng);
    for (int c = rep(rng) > 10 ? 3 : 1; c > 0; --c) {
      ring.insert(ring.end(), {r * std::cos(a), r * std::sin(a), z});
    }
  }
  const auto box = uniformCloud(5000, 3.f, 3.f, 3.f, 32);
  const std::vector<const std::vector<float>*> clouds = {&ring, &box};
  for (const std::vector<float>* xyz : clouds) {
    for (int k : {1, 8, 32, 33, 50, 64}) {
      // Brute force checks every row of one variant; the others must give the same bits.
      Lists ref;
      for (int heavy : {0, 1, 300}) {  // 1: nearly every query split over 16 warps
        for (int merge_min : {0, 1, 2, 6, 33}) {
          for (bool skip : {false, true}) {
            CudaKnnTuning o;
            o.merge_min = merge_min;
            o.skip_duplicates = skip;
            o.heavy_candidates = heavy;
            const Lists l = runTuned(o, *xyz, k);
            if (ref.idx.empty()) {
              expectExact(*xyz, k, l);
              ref = l;
            } else {
              EXPECT_EQ(l.idx, ref.idx) << "k = " << k << ", merge_min = " << merge_min
                                        << ", skip_duplicates = " << skip << ", heavy = " << heavy;
              EXPECT_EQ(l.d2, ref.d2);
            }
          }
        }
      }
    }
  }
}

TEST_F(CudaKnnTest, ListsKeptOnDeviceFeedTheCounts) {
  const auto xyz = lidarLikeCloud(20000, 24);
  const std::size_t n = 20000;
  CudaKnn knn;
  const Lists a = run(knn, xyz, 30);
  EXPECT_EQ(knn.listPoints(), n);
  CudaKnn dev;
  std::vector<std::uint8_t> flags(n), valid(n);
  std::vector<std::uint16_t> flagged(n, 999), size(n, 999);
  EXPECT_THROW(dev.countFlaggedNeighbors(flags.data(), flagged.data(), size.data()),
               std::logic_error);
  dev.search(xyz.data(), n, 30, nullptr, nullptr);  // lists stay on the device
  EXPECT_EQ(dev.listPoints(), n);
  for (std::size_t i = 0; i < n; ++i) flags[i] = (i * 7919) % 3 == 0;
  dev.countFlaggedNeighbors(flags.data(), flagged.data(), size.data());
  std::size_t bad = 0;
  for (std::size_t i = 0; i < n; ++i) {
    int u = 0;
    for (int j = 0; j < 30; ++j) u += flags[a.idx[i * 30 + j]];
    bad += flagged[i] != u || size[i] != 30;
  }
  EXPECT_EQ(bad, 0u);
  // A cloud smaller than K: counts stop at the padding.
  const auto tiny = lidarLikeCloud(7, 25);
  dev.search(tiny.data(), 7, 30, nullptr, nullptr);
  std::vector<std::uint8_t> ones(7, 1);
  dev.countFlaggedNeighbors(ones.data(), flagged.data(), size.data());
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(size[i], 7);
    EXPECT_EQ(flagged[i], 7);
  }
  // PCA of the kept lists: unit normals for valid points.
  std::vector<float> normals(3 * 7), eigen(3 * 7);
  dev.neighborhoodPca(normals.data(), eigen.data(), valid.data());
  for (int i = 0; i < 7; ++i) {
    ASSERT_TRUE(valid[i]);
    const float len =
        std::sqrt(normals[3 * i] * normals[3 * i] + normals[3 * i + 1] * normals[3 * i + 1] +
                  normals[3 * i + 2] * normals[3 * i + 2]);
    EXPECT_NEAR(len, 1.f, 1e-5f);
    EXPECT_NEAR(eigen[3 * i] + eigen[3 * i + 1] + eigen[3 * i + 2], 1.f, 1e-5f);
  }
}

TEST_F(CudaKnnTest, MemoryLimitGivesAClearCudaError) {
  CudaKnnOptions opt;
  opt.memory_limit = 1 << 20;  // 1 MiB: far too small for 100 k points at K = 50
  CudaKnn knn(opt);
  const auto xyz = lidarLikeCloud(100000, 22);
  std::vector<std::int32_t> idx(100000 * 50);
  std::vector<float> d2(100000 * 50);
  try {
    knn.search(xyz.data(), 100000, 50, idx.data(), d2.data());
    FAIL() << "no error under a 1 MiB limit";
  } catch (const CudaError& e) {
    EXPECT_EQ(e.errorName(), "cudaErrorMemoryAllocation");
    EXPECT_NE(std::string(e.what()).find("memory limit"), std::string::npos) << e.what();
  }
  EXPECT_LE(knn.deviceBytes(), opt.memory_limit);
  // A small cloud still fits under the limit.
  const auto tiny = lidarLikeCloud(500, 23);
  expectExact(tiny, 16, run(knn, tiny, 16));
}

}  // namespace
