// KdTreeNeighborSearch: exact lists against brute force (every row is the K smallest (squared
// distance, index) pairs, so the expected lists are unique), under every SIMD level the CPU has
// (portable, AVX2, AVX-512, NEON: each has its own query code); and against nanoflann on a real
// KITTI frame.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gf_test_data.h"
#include "gf_test_points.h"
#include "ground_filter/cloud_view.h"
#include "knn/kdtree_neighbor_search.h"
#include "knn/kdtree_tree.h"
#include "knn/neighborhood_pca.h"
#include "simd/simd.h"

// nanoflann is an optional test dependency (CMakeLists.txt defines GF_HAVE_NANOFLANN when found).
#ifdef GF_HAVE_NANOFLANN
#define NANOFLANN_FIRST_MATCH
#include <nanoflann.hpp>
// 1.5.0 renamed SearchParams to SearchParameters (CMakeLists.txt asks the header which it has).
#if GF_NANOFLANN_SEARCH_PARAMETERS
using NanoflannSearchParams = nanoflann::SearchParameters;
#else
using NanoflannSearchParams = nanoflann::SearchParams;
#endif
#endif

namespace gf = ground_filter;

namespace {

using Cloud = std::vector<float>;  // packed x y z

/// Squared distance as the search computes it: float, (dx*dx + dy*dy) + dz*dz.
float sqDist(const Cloud& c, std::size_t a, std::size_t b) {
  const float dx = c[3 * a] - c[3 * b], dy = c[3 * a + 1] - c[3 * b + 1],
              dz = c[3 * a + 2] - c[3 * b + 2];
  return dx * dx + dy * dy + dz * dz;
}

/// The expected lists: for every point the K smallest (squared distance, index), then padding.
gf::NeighborLists bruteForce(const Cloud& c, int k) {
  const std::size_t n = c.size() / 3;
  gf::NeighborLists l;
  l.k = k;
  l.points = n;
  l.indices.assign(n * k, -1);
  l.sq_dists.assign(n * k, std::numeric_limits<float>::infinity());
  std::vector<std::pair<float, std::int32_t>> all(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) all[j] = {sqDist(c, i, j), static_cast<std::int32_t>(j)};
    const std::size_t found = std::min<std::size_t>(k, n);
    std::partial_sort(all.begin(), all.begin() + found, all.end());
    for (std::size_t j = 0; j < found; ++j) {
      l.sq_dists[i * k + j] = all[j].first;
      l.indices[i * k + j] = all[j].second;
    }
  }
  return l;
}

using Level = gf::simd::Level;

/// The SIMD levels with their own query code that this CPU runs: portable always, AVX2 and
/// AVX-512 (x86-64) or NEON (aarch64) where available (a test runs each under
/// gf::simd::ScopedLevel).
std::vector<Level> codePaths() {
  std::vector<Level> levels;
  for (Level l : {Level::kPortable, Level::kNeon, Level::kAvx2, Level::kAvx512}) {
    if (gf::simd::supported(l)) levels.push_back(l);
  }
  return levels;
}

std::string nameOf(Level l) { return gf::simd::levelName(l); }

/// Runs `body(level)` once under each code path of codePaths() (a failure names the path).
template <typename Body>
void forEachCodePath(Body body) {
  for (Level level : codePaths()) {
    const gf::simd::ScopedLevel scoped(level);
    ASSERT_TRUE(scoped.ok());
    SCOPED_TRACE(nameOf(level));
    body(level);
  }
}

void expectSameLists(const gf::NeighborLists& want, const gf::NeighborLists& got) {
  ASSERT_EQ(got.k, want.k);
  ASSERT_EQ(got.points, want.points);
  ASSERT_EQ(got.indices.size(), want.indices.size());
  ASSERT_EQ(got.sq_dists.size(), want.sq_dists.size());
  std::size_t bad_rows = 0;
  for (std::size_t i = 0; i < want.points; ++i) {
    const std::size_t b = i * want.k, e = b + want.k;
    const bool same =
        std::equal(want.indices.begin() + b, want.indices.begin() + e, got.indices.begin() + b) &&
        std::memcmp(&want.sq_dists[b], &got.sq_dists[b], sizeof(float) * want.k) == 0;
    if (!same && bad_rows++ < 3) ADD_FAILURE() << "row " << i << " differs";
  }
  EXPECT_EQ(bad_rows, 0u);
}

Cloud randomCloud(std::size_t n, unsigned seed, bool clustered) {
  return gf_test::randomCloud(n, seed, clustered, 0.2f);
}

#ifdef GF_HAVE_NANOFLANN
/// nanoflann dataset adaptor (the reference exact search on a real scan).
struct NanoflannCloud {
  const Cloud* c;
  std::size_t kdtree_get_point_count() const { return c->size() / 3; }
  float kdtree_get_pt(std::uint32_t i, std::size_t d) const { return (*c)[3 * i + d]; }
  template <class B>
  bool kdtree_get_bbox(B& /*bb*/) const {
    return false;
  }
};
// L2_Simple_Adaptor's index type argument only exists since 1.4: left at its default.
using NanoflannTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, NanoflannCloud>,
                                        NanoflannCloud, 3, std::uint32_t>;
#endif  // GF_HAVE_NANOFLANN

}  // namespace

TEST(KdTreeNeighborSearchExact, RandomCloudsEveryK) {
  // K up to 64, 128 and 256 use different AVX-512 list sizes; 300 only the portable code.
  forEachCodePath([&](Level level) {
    gf::KdTreeNeighborSearch search(2, 16);
    gf::NeighborLists got;
    for (bool clustered : {false, true}) {
      const Cloud c = randomCloud(1200, clustered ? 7u : 3u, clustered);
      for (int k : {1, 2, 8, 50, 64, 65, 128, 129, 256, 300}) {
        SCOPED_TRACE(nameOf(level) + " clustered " + std::to_string(clustered) + " k " +
                     std::to_string(k));
        search.search(c.data(), c.size() / 3, k, &got);
        expectSameLists(bruteForce(c, k), got);
      }
    }
  });
}

namespace {

// A lidar's no-return points all at the origin (more than a leaf and more than K), some points
// on top of each other elsewhere, and scattered points around.
Cloud coincidentCloud() {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-3.f, 3.f);
  Cloud c;
  for (int i = 0; i < 1500; ++i) {
    if (i % 3 == 0) {
      c.insert(c.end(), {0.f, 0.f, 0.f});
    } else if (i % 7 == 0) {
      c.insert(c.end(), {1.f, 2.f, -0.5f});
    } else {
      c.insert(c.end(), {u(rng), u(rng), u(rng)});
    }
  }
  return c;
}

}  // namespace

TEST(KdTreeNeighborSearchExact, ManyCoincidentPoints) {
  const Cloud c = coincidentCloud();
  forEachCodePath([&](Level level) {
    for (int leaf : {4, 32}) {
      gf::KdTreeNeighborSearch search(2, leaf);
      gf::NeighborLists got;
      for (int k : {10, 50, 200}) {
        SCOPED_TRACE(nameOf(level) + " leaf " + std::to_string(leaf) + " k " + std::to_string(k));
        search.search(c.data(), c.size() / 3, k, &got);
        expectSameLists(bruteForce(c, k), got);
      }
    }
  });
}

TEST(KdTreeNeighborSearchExact, OneAndTwoBuildThreadsAgree) {
  // The build places each leaf's points in index order, with two threads from both ends of every
  // leaf: odd sizes, coincident points on both sides of n / 2, default leaf size.
  forEachCodePath([&](Level level) {
    for (std::size_t n : {257u, 1001u, 4099u}) {
      Cloud c = randomCloud(n, 5u, true);
      for (std::size_t i = 0; i < n; i += 5) c[3 * i] = c[3 * i + 1] = c[3 * i + 2] = 0.f;
      for (int threads : {1, 2}) {
        for (int leaf : {8, 64}) {
          gf::KdTreeNeighborSearch search(threads, leaf);
          gf::NeighborLists got;
          for (int k : {1, 64, 129}) {
            SCOPED_TRACE(nameOf(level) + " n " + std::to_string(n) + " threads " +
                         std::to_string(threads) + " leaf " + std::to_string(leaf) + " k " +
                         std::to_string(k));
            search.search(c.data(), n, k, &got);
            expectSameLists(bruteForce(c, k), got);
          }
        }
      }
    }
  });
}

TEST(KdTreeNeighborSearchExact, GroupListsOverflowAndMisses) {
  // The AVX2 / AVX-512 query code searches the queries of a leaf from one list of the leaves
  // within reach of it (kdtree_tree.h, queryRange()). One-point leaves with K = 256 put more
  // leaves in reach than a list holds (each query then descends); a cloud whose spacing grows
  // tenfold from one stretch to the next leaves queries with fewer than K points on their list
  // (they descend with their bound). Both must stay exact.
  Cloud cube = randomCloud(3000, 13u, false), stretches;
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  float x = 0.f;
  for (int s = 0; s < 4; ++s) {
    const float step = 0.001f * std::pow(10.f, static_cast<float>(s));
    for (int i = 0; i < 400; ++i) {
      x += step;
      stretches.insert(stretches.end(), {x, step * u(rng), step * u(rng)});
    }
  }
  forEachCodePath([&](Level level) {
    gf::NeighborLists got;
    for (int leaf : {1, 8}) {
      gf::KdTreeNeighborSearch search(2, leaf);
      for (int k : {40, 256}) {
        SCOPED_TRACE(nameOf(level) + " leaf " + std::to_string(leaf) + " k " + std::to_string(k));
        search.search(cube.data(), cube.size() / 3, k, &got);
        expectSameLists(bruteForce(cube, k), got);
        search.search(stretches.data(), stretches.size() / 3, k, &got);
        expectSameLists(bruteForce(stretches, k), got);
      }
    }
  });
}

TEST(KdTreeNeighborSearchExact, RegularGridTiesAndLine) {
  // Many neighbours at exactly the same distance: the lower index must win every tie.
  Cloud grid, line;
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 10; ++j) {
      for (int l = 0; l < 4; ++l) grid.insert(grid.end(), {0.5f * i, 0.5f * j, 0.5f * l});
    }
  }
  for (int i = 0; i < 300; ++i) line.insert(line.end(), {0.1f * (i % 150), 2.f, 1.f});  // doubled
  forEachCodePath([&](Level level) {
    gf::KdTreeNeighborSearch search(1, 8);
    gf::NeighborLists got;
    for (const Cloud* c : {&grid, &line}) {
      for (int k : {7, 27, 50}) {
        SCOPED_TRACE(nameOf(level) + " k " + std::to_string(k));
        search.search(c->data(), c->size() / 3, k, &got);
        expectSameLists(bruteForce(*c, k), got);
      }
    }
  });
}

TEST(KdTreeNeighborSearchExact, SmallClouds) {
  forEachCodePath([&](Level level) {
    gf::KdTreeNeighborSearch search(2);
    gf::NeighborLists got;
    for (std::size_t n : {1u, 2u, 49u, 50u, 51u}) {
      const Cloud c = randomCloud(n, 5, true);
      SCOPED_TRACE(nameOf(level) + " n " + std::to_string(n));
      search.search(c.data(), n, 50, &got);
      expectSameLists(bruteForce(c, 50), got);
    }
  });
}

TEST(KdTreeNeighborSearchExact, AllPointsIdenticalEveryLevel) {
  // Every distance 0: the lists are the K lowest indices, on every level, also for K up to 256
  // and for fewer points than K.
  forEachCodePath([&](Level level) {
    for (std::size_t n : {10u, 700u}) {
      const Cloud c(3 * n, 1.25f);
      gf::KdTreeNeighborSearch search(2, 16);
      gf::NeighborLists got;
      for (int k : {1, 5, 64, 200, 256}) {
        SCOPED_TRACE(nameOf(level) + " n " + std::to_string(n) + " k " + std::to_string(k));
        search.search(c.data(), n, k, &got);
        expectSameLists(bruteForce(c, k), got);
      }
    }
  });
}

TEST(KdTreeNeighborSearchExact, InfiniteDistancesEveryLevel) {
  // Points at +-1e30: their squared distances to the others overflow to +Inf, so rows of the
  // finite points end in ties at Inf (lower index first) and the far points' rows hold every
  // finite point at Inf. The boxes' distances overflow the same way.
  Cloud c = randomCloud(400, 9u, true);
  for (std::size_t i = 0; i < 400; i += 13) {
    c[3 * i] = (i % 2 ? 1e30f : -1e30f);
    c[3 * i + 2] = 1e30f;
  }
  // The same with some points on one spot: a leaf of them stops the splits early, so the tree
  // has a leaf count that is no power of two (a group's list of every leaf, as an infinite reach
  // gives, then ends in padding, which must not be scanned).
  Cloud d = c;
  for (std::size_t i = 5; i < 400; i += 7) d[3 * i] = d[3 * i + 1] = d[3 * i + 2] = 0.5f;
  forEachCodePath([&](Level level) {
    gf::KdTreeNeighborSearch search(2, 8);
    gf::NeighborLists got;
    for (const Cloud* cloud : {&c, &d}) {
      for (int k : {3, 64, 256}) {
        SCOPED_TRACE(nameOf(level) + " k " + std::to_string(k));
        search.search(cloud->data(), cloud->size() / 3, k, &got);
        expectSameLists(bruteForce(*cloud, k), got);
      }
    }
  });
}

TEST(KdTreeNeighborSearchExact, LevelsAgreeOnLargeK) {
  // K of every list size of the SIMD codes (AVX2: 16, 32, 64, 128, 256 slots; AVX-512: 64, 128,
  // 256) on clustered clouds with duplicates: lists identical to the portable code's.
  const Cloud c = randomCloud(5000, 21u, true);
  for (int k : {16, 17, 32, 33, 63, 64, 100, 128, 129, 255, 256}) {
    std::vector<gf::NeighborLists> lists;
    forEachCodePath([&](Level) {
      gf::KdTreeNeighborSearch search(2, 64);
      lists.emplace_back();
      search.search(c.data(), c.size() / 3, k, &lists.back());
    });
    for (std::size_t p = 1; p < lists.size(); ++p) {
      SCOPED_TRACE(nameOf(codePaths()[p]) + " k " + std::to_string(k));
      expectSameLists(lists.front(), lists[p]);
    }
  }
}

TEST(KdTreeNeighborSearchExact, KittiFrameMatchesNanoflann) {
  // A real scan (124 k points, K = 50): distances identical to nanoflann's exact search, the
  // neighbour sets identical up to ties at the K-th distance, both code paths identical.
#ifndef GF_HAVE_NANOFLANN
  GTEST_SKIP() << "nanoflann not found at configure time (optional test dependency, 1.3-1.7)";
#else
  const std::string file = std::string(GF_DATA_DIR) + "/semantickitti/seq00/000000.bin";
  GF_SKIP_WITHOUT_DATA(file);
  const Cloud c = gf_test::finiteXyzOf(file);
  const std::size_t n = c.size() / 3;
  ASSERT_GT(n, 100000u);
  constexpr int k = 50;

  const NanoflannCloud adaptor{&c};
  NanoflannTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();  // 1.3.x does not build in the constructor (later ones just rebuild)
  std::vector<std::uint32_t> ref_idx(n * k);
  std::vector<float> ref_dist(n * k);
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
    nanoflann::KNNResultSet<float, std::uint32_t, std::uint32_t> result(k);
    result.init(&ref_idx[i * k], &ref_dist[i * k]);
    tree.findNeighbors(result, &c[3 * i], NanoflannSearchParams());
  }

  std::vector<gf::NeighborLists> lists;
  forEachCodePath([&](Level) {
    gf::KdTreeNeighborSearch search(0);
    lists.emplace_back();
    search.search(c.data(), n, k, &lists.back());
  });
  const gf::NeighborLists& got = lists.front();
  std::size_t dist_rows = 0, set_rows = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float* rd = &ref_dist[i * k];
    dist_rows += std::memcmp(rd, &got.sq_dists[i * k], sizeof(float) * k) != 0;
    const float kth = rd[k - 1];
    std::vector<std::int32_t> a, b;
    for (int j = 0; j < k; ++j) {
      if (rd[j] < kth) a.push_back(static_cast<std::int32_t>(ref_idx[i * k + j]));
      if (got.sq_dists[i * k + j] < kth) b.push_back(got.indices[i * k + j]);
    }
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    set_rows += a != b;
  }
  EXPECT_EQ(dist_rows, 0u) << "rows whose distances differ from nanoflann's";
  EXPECT_EQ(set_rows, 0u) << "rows whose neighbours (inside the K-th distance) differ";
  for (std::size_t p = 1; p < lists.size(); ++p) expectSameLists(lists.front(), lists[p]);
#endif  // GF_HAVE_NANOFLANN
}

namespace {

/// Kept lists (keepLists(true), tree-order rows) against the reference search() lists of
/// a second object: same rows, PCA bit for bit, neighbour counts of random flags identical.
void expectKeptListsSame(const Cloud& c, int k, Level level, int leaf) {
  const gf::simd::ScopedLevel scoped(level);
  ASSERT_TRUE(scoped.ok());
  const std::size_t n = c.size() / 3;
  gf::KdTreeNeighborSearch ref(2, leaf), kept(2, leaf);
  EXPECT_TRUE(kept.keepLists(true));
  gf::NeighborLists want, out, got;
  ref.search(c.data(), n, k, &want);
  std::vector<gf::PointPca> want_pca, got_pca;
  gf::computeNeighborhoodPca(c.data(), want, 1, &want_pca);
  ASSERT_TRUE(kept.searchWithPca(c.data(), n, k, &out, &got_pca));
  const bool full = n >= static_cast<std::size_t>(k);
  ASSERT_EQ(kept.keptLists(&got), full);
  if (full) {
    EXPECT_TRUE(out.indices.empty());
    expectSameLists(want, got);
  } else {
    expectSameLists(want, out);  // fewer points than K: lists in `out` as without keeping
  }
  ASSERT_EQ(got_pca.size(), n);
  std::size_t pca_diff = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const gf::PointPca &a = want_pca[i], &b = got_pca[i];
    pca_diff += a.valid != b.valid || std::memcmp(a.normal, b.normal, sizeof a.normal) != 0 ||
                std::memcmp(a.eigen, b.eigen, sizeof a.eigen) != 0;
  }
  EXPECT_EQ(pca_diff, 0u) << "points whose PCA differs";
  std::mt19937 rng(5);
  std::vector<std::uint8_t> flags(n);
  for (auto& f : flags) f = rng() % 3 == 0;
  std::vector<std::uint16_t> flagged(n), size(n);
  ASSERT_EQ(kept.countFlaggedNeighbors(flags.data(), flagged.data(), size.data()), full);
  EXPECT_FALSE(ref.countFlaggedNeighbors(flags.data(), flagged.data(), size.data()));
  if (!full) return;
  std::size_t count_diff = 0;
  for (std::size_t i = 0; i < n; ++i) {
    int u = 0, m = 0;
    for (; m < k && want.indices[i * k + m] >= 0; ++m) u += flags[want.indices[i * k + m]];
    count_diff += flagged[i] != u || size[i] != m;
  }
  EXPECT_EQ(count_diff, 0u) << "points whose flagged-neighbour count differs";
}

}  // namespace

TEST(KdTreeNeighborSearchExact, KeptListsSameAsReference) {
  const Cloud coincident = coincidentCloud();
  forEachCodePath([&](Level level) {
    for (bool clustered : {false, true}) {
      const Cloud c = randomCloud(3000, clustered ? 7u : 3u, clustered);
      for (int k : {1, 8, 64, 65, 300}) {
        SCOPED_TRACE(nameOf(level) + " clustered " + std::to_string(clustered) + " k " +
                     std::to_string(k));
        expectKeptListsSame(c, k, level, 16);
      }
    }
    for (int k : {10, 64}) {
      SCOPED_TRACE("coincident " + nameOf(level) + " k " + std::to_string(k));
      expectKeptListsSame(coincident, k, level, 4);
    }
    SCOPED_TRACE("small cloud");
    expectKeptListsSame(randomCloud(40, 5, true), 64, level, 64);
  });
}

TEST(KdTreeNeighborSearchExact, KeptListsSameOnRealScans) {
  // The dev frames the speed goal is measured on (K = 64, the default), where available.
  const std::vector<std::string> files = {
      std::string(GF_DATA_DIR) + "/semantickitti/seq00/000000.bin",
      std::string(GF_DATA_DIR) + "/unlabelled/os128_000000.pcd"};
  std::size_t tested = 0;
  for (const std::string& file : files) {
    if (!gf_test::dataExists(file)) continue;
    const Cloud c = gf_test::finiteXyzOf(file);
    if (c.empty()) continue;  // a file the build cannot read (test/core_only: .bin only)
    SCOPED_TRACE(file);
    for (Level level : codePaths()) {
      SCOPED_TRACE(nameOf(level));
      expectKeptListsSame(c, 64, level, 64);
    }
    ++tested;
  }
  if (tested == 0) GTEST_SKIP() << "no dev frames under " << GF_DATA_DIR;
}

namespace {

/// PCA bits and candidate bytes of the lists `l` under every SIMD level, against the portable
/// code's (each level has its own neighbourhood sums).
void expectPcaSameOnEveryLevel(const Cloud& c, const gf::NeighborLists& l) {
  const std::size_t n = c.size() / 3;
  gf::CandidateTest test;
  test.min_planarity = 0.2;
  test.min_abs_nz = std::cos(30.0 * M_PI / 180.0);
  std::vector<gf::PointPca> want, got;
  std::vector<std::uint8_t> want_cand(n), got_cand(n);
  {
    const gf::simd::ScopedLevel scoped(Level::kPortable);
    ASSERT_TRUE(scoped.ok());
    gf::computeNeighborhoodPca(c.data(), l, 2, &want);
    gf::computeNeighborhoodCandidates(c.data(), l, 2, test, want_cand.data(), nullptr);
  }
  std::size_t candidates = 0;
  for (std::size_t i = 0; i < n; ++i) {
    // The reference decision, so that the candidate check could fail.
    ASSERT_EQ(want_cand[i], gf::isCandidatePca(want[i], test.min_planarity, test.min_abs_nz));
    candidates += want_cand[i];
  }
  forEachCodePath([&](Level level) {
    SCOPED_TRACE(nameOf(level));
    gf::computeNeighborhoodPca(c.data(), l, 2, &got);
    gf::computeNeighborhoodCandidates(c.data(), l, 2, test, got_cand.data(), nullptr);
    ASSERT_EQ(got.size(), n);
    std::size_t pca_diff = 0, cand_diff = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const gf::PointPca &a = want[i], &b = got[i];
      pca_diff += a.valid != b.valid || std::memcmp(a.normal, b.normal, sizeof a.normal) != 0 ||
                  std::memcmp(a.eigen, b.eigen, sizeof a.eigen) != 0;
      cand_diff += want_cand[i] != got_cand[i];
    }
    EXPECT_EQ(pca_diff, 0u) << "points whose PCA differs from the portable code's";
    EXPECT_EQ(cand_diff, 0u) << "points whose candidate flag differs (" << candidates
                             << " candidates)";
  });
}

}  // namespace

TEST(KdTreeNeighborSearchExact, PcaSameBitsOnEveryLevel) {
  // Random clouds (full rows, rows of fewer points than K, coincident points) and a KITTI frame.
  gf::KdTreeNeighborSearch search(2, 16);
  gf::NeighborLists l;
  for (std::size_t n : {20u, 3000u}) {
    for (int k : {3, 16, 64, 129}) {
      SCOPED_TRACE("n " + std::to_string(n) + " k " + std::to_string(k));
      const Cloud c = randomCloud(n, 13u, true);
      search.search(c.data(), n, k, &l);
      expectPcaSameOnEveryLevel(c, l);
    }
  }
  const Cloud same(3 * 100, -2.5f);  // all points identical: every PCA invalid
  search.search(same.data(), 100, 64, &l);
  expectPcaSameOnEveryLevel(same, l);
  const std::string file = std::string(GF_DATA_DIR) + "/semantickitti/seq00/000000.bin";
  if (!gf_test::dataExists(file)) return;  // the random clouds above still ran
  const Cloud c = gf_test::finiteXyzOf(file);
  search.search(c.data(), c.size() / 3, 64, &l);
  SCOPED_TRACE(file);
  expectPcaSameOnEveryLevel(c, l);
}

TEST(KdTreeBuild, EverySplitIsAtTheMedian) {
  // The build selects each node's median along its widest axis (std::nth_element above 4096
  // points, its own quickselect below): then every inner node's halves have equal sizes (the
  // left one the smaller by one at most) and their boxes meet at most at the median's key
  // along some axis. Inputs that trip quickselects: sorted, reversed, few distinct keys,
  // runs of one value, a grid; sizes above and below the switch.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-50.f, 50.f);
  std::vector<std::pair<std::string, Cloud>> clouds;
  for (std::size_t n : {300u, 5000u, 20000u}) {
    Cloud rnd, sorted, reversed, few, runs;
    for (std::size_t i = 0; i < n; ++i) {
      rnd.insert(rnd.end(), {u(rng), u(rng), 0.1f * u(rng)});
      sorted.insert(sorted.end(), {0.01f * i, 0.f, 0.f});
      reversed.insert(reversed.end(), {-0.01f * i, 0.001f * (i % 3), 0.f});
      few.insert(few.end(), {static_cast<float>(i % 3), 0.01f * u(rng), 0.f});
      runs.insert(runs.end(), {i < n / 2 ? 0.f : static_cast<float>(i % 5), 1e-4f * i, 0.f});
    }
    for (auto* c : {&rnd, &sorted, &reversed, &few, &runs}) {
      const char* name = c == &rnd        ? "random"
                         : c == &sorted   ? "sorted"
                         : c == &reversed ? "reversed"
                         : c == &few      ? "three keys"
                                          : "runs";
      clouds.emplace_back(std::string(name) + " " + std::to_string(n), *c);
    }
  }
  Cloud grid;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j) {
      for (int l = 0; l < 4; ++l) grid.insert(grid.end(), {0.5f * i, 0.5f * j, 0.5f * l});
    }
  }
  clouds.emplace_back("grid 6400", grid);
  for (const auto& named : clouds) {
    SCOPED_TRACE(named.first);
    const Cloud& c = named.second;
    gf::kdtree::KdTree t;
    t.leaf = 8;
    t.build(c.data(), c.size() / 3, 10, 2);
    std::size_t inner = 0;
    for (const gf::kdtree::Node& nd : t.nodes) {
      if (nd.left < 0 || nd.right <= 0 || nd.right == gf::kdtree::kSamePoint) continue;
      if (nd.scan_end <= nd.begin) continue;  // an unused slot
      const gf::kdtree::Node& l = t.nodes[static_cast<std::size_t>(nd.left)];
      const gf::kdtree::Node& r = t.nodes[static_cast<std::size_t>(nd.right)];
      ++inner;
      ASSERT_EQ(l.begin, nd.begin);
      ASSERT_EQ(r.begin, nd.begin + (nd.scan_end - nd.begin) / 2);
      bool apart = false;
      for (int d = 0; d < 3; ++d) apart = apart || l.hi[d] <= r.lo[d];
      ASSERT_TRUE(apart) << "node of " << nd.scan_end - nd.begin << " points at " << nd.begin;
    }
    EXPECT_GT(inner, c.size() / 3 / 16);
  }
}
