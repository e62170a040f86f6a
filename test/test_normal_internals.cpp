// Normal-vector filter internals: the same labels on every SIMD level, the radix sort of the
// stages, huge-page advice on large scratch buffers, the local-ground stage.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/radix_sort.h"
#include "eval/metrics.h"
#include "eval/scan_io.h"
#include "eval/scene_generator.h"
#include "gf_test_data.h"
#include "gf_test_normal.h"
#include "gf_test_points.h"
#include "gf_test_scenes.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/neighbor_search.h"
#include "ground_filter/normal_ground_filter.h"
#include "knn/kdtree_neighbor_search.h"
#include "knn/neighborhood_pca.h"
#include "normal/cpu_gpu_common.h"
#include "normal/lattice.h"
#include "normal/local_ground.h"
#include "normal/plane.h"
#include "normal/sample.h"
#include "simd/simd.h"

namespace gf = ground_filter;

using gf_test_normal::add;
using gf_test_normal::Cloud;
using gf_test_normal::plane;

namespace {

/// The SIMD levels with their own normal-filter code (kd-tree queries, neighbourhood sums) that
/// this CPU runs.
std::vector<gf::simd::Level> normalCodeLevels() {
  std::vector<gf::simd::Level> levels;
  for (gf::simd::Level l :
       {gf::simd::Level::kPortable, gf::simd::Level::kAvx2, gf::simd::Level::kAvx512}) {
    if (gf::simd::supported(l)) levels.push_back(l);
  }
  return levels;
}

/// Labels of `view` with the defaults (2 threads) under every level, against the portable ones.
void expectSameLabelsOnEveryLevel(const gf::CloudView& view, int k) {
  gf::NormalGroundFilterParams p;
  p.threads = 2;
  p.k = k;
  std::vector<std::uint8_t> want, got;
  {
    const gf::simd::ScopedLevel scoped(gf::simd::Level::kPortable);
    ASSERT_TRUE(scoped.ok());
    gf::NormalGroundFilter f(p);
    f.filter(view, &want);
  }
  ASSERT_EQ(want.size(), view.size());
  std::size_t ground = 0;
  for (std::uint8_t l : want) ground += l == 1;
  for (gf::simd::Level level : normalCodeLevels()) {
    const gf::simd::ScopedLevel scoped(level);
    ASSERT_TRUE(scoped.ok());
    gf::NormalGroundFilter f(p);
    f.filter(view, &got);
    f.filter(view, &got);  // the second scan on kept scratch memory
    std::size_t diff = 0;
    for (std::size_t i = 0; i < want.size(); ++i) diff += want[i] != got[i];
    EXPECT_EQ(diff, 0u) << gf::simd::levelName(level) << ": labels differing from the portable "
                        << "code's (" << ground << " ground of " << want.size() << ")";
  }
}

}  // namespace

TEST(NormalGroundFilterSimd, KittiLabelsSameOnEveryLevel) {
  const std::string file = std::string(GF_DATA_DIR) + "/semantickitti/seq00/000000.bin";
  GF_SKIP_WITHOUT_DATA(file);
  const gf::Scan scan = gf::loadScan(file);
  expectSameLabelsOnEveryLevel(gf::viewOf(scan.cloud), 64);
}

TEST(NormalGroundFilterSimd, BadInputSameOnEveryLevel) {
  // A ground plane with NaN / Inf points, a pile of identical points, and clouds smaller than K.
  Cloud c = plane(20.0, 0.25, -1.7, 0.05, 0.02, 4);
  const float nan = std::numeric_limits<float>::quiet_NaN(),
              inf = std::numeric_limits<float>::infinity();
  for (std::size_t i = 0; i < c.size() / 3; i += 17) c[3 * i + (i % 3)] = i % 2 ? nan : inf;
  for (int i = 0; i < 300; ++i) add(&c, 2.0, 3.0, -1.2);
  for (int k : {8, 64}) {
    SCOPED_TRACE("k " + std::to_string(k));
    expectSameLabelsOnEveryLevel(gf::CloudView::packedXyz(c.data(), c.size() / 3), k);
  }
  const Cloud small(c.begin(), c.begin() + 3 * 40);
  expectSameLabelsOnEveryLevel(gf::CloudView::packedXyz(small.data(), 40), 64);
  const Cloud same(3 * 100, 1.5f);
  expectSameLabelsOnEveryLevel(gf::CloudView::packedXyz(same.data(), 100), 64);
}

TEST(NormalPlaneFit, SkippedDrawsAreTheSequencesLaterDraws) {
  // The GPU scores several RANSAC draws at once, each generator skipped to its own draw.
  for (std::uint64_t n : {0ull, 1ull, 2ull, 3ull, 299ull, 1000003ull}) {
    gf::normal::SplitMix64 a(gf::normal::ransacBaseSeed(7)), b(gf::normal::ransacBaseSeed(7));
    a.skip(n);
    for (std::uint64_t i = 0; i < n; ++i) b.next();
    for (int i = 0; i < 4; ++i) EXPECT_EQ(a.next(), b.next()) << n;
  }
}

TEST(NormalPlaneFit, LaneSumsGiveTheLeastSquaresPlane) {
  // Points on z = 0.05 x - 0.02 y + 1 (1 cm noise) and 20 % above it: the refit, summed in
  // kPlaneSumLanes lanes, must give the true plane with fewer points than lanes, a few more, and
  // many per lane.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-20.f, 20.f), up(0.5f, 2.f);
  std::normal_distribution<float> noise(0.f, 0.01f);
  const Eigen::Vector3d truth = Eigen::Vector3d(-0.05, 0.02, 1.0).normalized();
  for (std::size_t m : {std::size_t(60), std::size_t(128), std::size_t(129), std::size_t(4097),
                        std::size_t(100000)}) {
    std::vector<float> xyz;
    std::vector<std::uint32_t> idx;
    for (std::size_t i = 0; i < m; ++i) {
      const float x = u(rng), y = u(rng);
      const float z = 0.05f * x - 0.02f * y + 1.f + (i % 5 == 4 ? up(rng) : noise(rng));
      xyz.insert(xyz.end(), {x, y, z});
      idx.push_back(static_cast<std::uint32_t>(i));
    }
    std::vector<std::uint32_t> scratch;
    gf::Plane pl;
    ASSERT_TRUE(gf::normal::fitPlaneRansac(xyz.data(), idx, 100, 0.05, 0.7, 11, &scratch, &pl));
    EXPECT_GT(std::abs(pl.normal.dot(truth)), 1.0 - 1e-4) << m;
    double worst = 0.0, mean = 0.0;  // the inliers' distances: centred on the plane, small
    for (std::size_t i = 0; i < m; i += 5) {
      const double d = pl.distance(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
      worst = std::max(worst, std::abs(d));
      mean += d;
    }
    EXPECT_LT(worst, 0.05) << m;
    EXPECT_LT(std::abs(mean / static_cast<double>((m + 4) / 5)), 0.005) << m;
  }
}

TEST(NormalSampleStage, GathersEveryStrideThPointAndSpreadsTheVotes) {
  gf::normal::SampleStage st;
  std::vector<float> xyz;
  for (int i = 0; i < 7; ++i) xyz.insert(xyz.end(), {float(i), float(10 * i), float(-i)});
  const gf::normal::ColumnGrid grid{0.0, 0.0, 10.0};  // every point in a column of its own
  for (int stride : {1, 2, 3, 7, 16}) {
    const std::size_t m = st.gather(xyz.data(), 7, stride, 40, grid);
    ASSERT_EQ(m, static_cast<std::size_t>((7 + stride - 1) / stride)) << stride;
    for (std::size_t j = 0; j < m; ++j) {
      EXPECT_EQ(st.sampledIndex()[j], j * stride) << stride;
      EXPECT_EQ(st.sampledXyz()[3 * j], float(j * stride)) << stride;
      EXPECT_EQ(st.sampledXyz()[3 * j + 1], float(10 * j * stride)) << stride;
      st.votes()[j] = static_cast<std::uint8_t>(j % 2);
      EXPECT_EQ(st.candidates()[j], 0) << stride;
    }
    EXPECT_EQ(st.sampledIndex()[m], 7u);
    std::vector<std::uint8_t> voted(7, 9);
    st.spread(voted.data());
    for (std::size_t i = 0; i < 7; ++i) {
      const std::size_t j = i / stride, next = std::min(j + 1, m - 1);
      const int expect = i % stride == 0 ? j % 2 : (j % 2) | (next % 2);
      EXPECT_EQ(voted[i], expect) << stride << " " << i;
    }
  }
  EXPECT_EQ(st.gather(xyz.data(), 0, 2, 40, grid), 0u);
}

TEST(NormalSampleStage, ADenseColumnGivesAtMostTheCapEvenlySpaced) {
  // Columns in order: 3 points, 25 and 9 points (over stride 2 * cap 4: capped), 8 points (not
  // over it), 1 point.
  const std::vector<int> counts = {3, 25, 9, 8, 1};
  std::vector<float> xyz;
  std::vector<std::size_t> begin;
  for (std::size_t c = 0; c < counts.size(); ++c) {
    begin.push_back(xyz.size() / 3);
    for (int i = 0; i < counts[c]; ++i) {
      xyz.insert(xyz.end(), {0.05f + float(c), 0.05f + 0.001f * float(i), float(i)});
    }
  }
  const std::size_t len = xyz.size() / 3;
  const gf::normal::ColumnGrid grid{0.0, 0.0, 10.0};  // 0.1 m columns
  gf::normal::SampleStage st;
  const std::size_t m = st.gather(xyz.data(), len, 2, 4, grid);
  const std::uint32_t* idx = st.sampledIndex();
  // Uncapped columns keep every 2nd point of the segment; capped ones start at their first point
  // and step ceil(count / 4): 25 -> 7 (0 7 14 21), 9 -> 3 (0 3 6).
  const std::vector<std::uint32_t> want = {0, 2, 3, 10, 17, 24, 28, 31, 34, 38, 40, 42, 44};
  ASSERT_EQ(m, want.size());
  for (std::size_t j = 0; j < m; ++j) EXPECT_EQ(idx[j], want[j]) << j;
  EXPECT_EQ(idx[m], len);
  for (std::size_t j = 0; j < m; ++j) st.votes()[j] = j == 3;
  std::vector<std::uint8_t> voted(len, 9);
  st.spread(voted.data());
  // Sampled point 3 (point 10) voted: itself and the points after sampled point 2 up to it.
  for (std::size_t i = 0; i < len; ++i) {
    EXPECT_EQ(voted[i], i >= 4 && i <= 16 ? 1 : 0) << i;
  }
  // Without a cap the old rule: every 2nd point.
  EXPECT_EQ(st.gather(xyz.data(), len, 2, 0, grid), (len + 1) / 2);
}

TEST(NormalSampleStage, CappedColumnsAreFoundAtAnyOffset) {
  // Random runs of column lengths around the threshold stride * cap: gather() (which probes every
  // h-th point for long columns) against the rule applied to every column.
  std::mt19937 rng(11);
  const gf::normal::ColumnGrid grid{0.0, 0.0, 10.0};
  gf::normal::SampleStage st;
  for (int round = 0; round < 200; ++round) {
    const int stride = 1 + static_cast<int>(rng() % 4), cap = 1 + static_cast<int>(rng() % 6);
    const int big = stride * cap;
    std::vector<float> xyz;
    std::vector<std::uint32_t> want;
    const int columns = 1 + static_cast<int>(rng() % 12);
    for (int c = 0; c < columns; ++c) {
      const int count = 1 + static_cast<int>(rng() % (3 * big + 2));
      const std::size_t a = xyz.size() / 3;
      for (int i = 0; i < count; ++i) xyz.insert(xyz.end(), {0.05f + float(c), 0.05f, 0.f});
      const std::size_t step = gf::normal::columnSampleStep(count, stride, cap);
      for (std::size_t i = a; i < a + count; ++i) {
        if (step == 0 ? i % stride == 0 : (i - a) % step == 0) {
          want.push_back(static_cast<std::uint32_t>(i));
        }
      }
    }
    const std::size_t len = xyz.size() / 3;
    const std::size_t m = st.gather(xyz.data(), len, stride, cap, grid);
    ASSERT_EQ(m, want.size()) << "round " << round;
    for (std::size_t j = 0; j < m; ++j) ASSERT_EQ(st.sampledIndex()[j], want[j]) << round;
    ASSERT_EQ(st.sampledIndex()[m], len);
  }
}

TEST(RadixSort, SortByKeyIsStableAndMatchesStdStableSort) {
  // The core's one sort (voxel keys, grid-column and tile keys): narrow and full-width keys,
  // many duplicates, constant keys, empty and single inputs; the same buffers reused.
  std::mt19937_64 rng(3);
  gf::RadixSortScratch scratch;
  std::vector<std::uint32_t> order;
  for (int bits : {0, 1, 8, 15, 16, 22, 31, 45, 64}) {
    for (std::size_t n : {0u, 1u, 2u, 17u, 5000u}) {
      std::vector<std::uint64_t> keys(n);
      const std::uint64_t mask = bits == 64 ? ~0ULL : (std::uint64_t{1} << bits) - 1;
      for (auto& k : keys) k = rng() & mask & (rng() % 4 == 0 ? ~0ULL : ~0xffULL);
      std::vector<std::uint32_t> want(n);
      for (std::size_t i = 0; i < n; ++i) want[i] = static_cast<std::uint32_t>(i);
      std::stable_sort(want.begin(), want.end(),
                       [&](std::uint32_t a, std::uint32_t b) { return keys[a] < keys[b]; });
      gf::radixSortByKey(keys, &order, &scratch);
      EXPECT_EQ(order, want) << "bits " << bits << ", n " << n;
      for (std::size_t j = 0; j < n; ++j) ASSERT_EQ(scratch.keys[j], keys[want[j]]) << j;
    }
  }
}

namespace {

// n packed key << slot | slot words (slots in order) of keys drawn by key(digit) with
// `key_bits` bits, the voxel filter's digit layout for them and the digit counts of every pass.
struct PackedWords {
  int slot_bits = 0, passes = 0, digit = 0;
  std::vector<std::uint64_t> words;
  std::vector<std::uint32_t> hist;
};
template <class Key>
PackedWords packedWords(int key_bits, std::size_t n, Key&& key) {
  PackedWords w;
  w.slot_bits = std::min(32, 64 - key_bits);
  w.passes = (key_bits + gf::kRadixMaxDigitBits - 1) / gf::kRadixMaxDigitBits;
  w.digit = (key_bits + w.passes - 1) / w.passes;
  const std::uint32_t dmask = (1u << w.digit) - 1;
  w.words.resize(n);
  w.hist.assign(static_cast<std::size_t>(w.passes) << w.digit, 0);
  for (std::size_t i = 0; i < n; ++i) {
    w.words[i] = key(w.digit) << w.slot_bits | i;
    for (int q = 0; q < w.passes; ++q) {
      ++w.hist[(static_cast<std::size_t>(q) << w.digit) +
               ((w.words[i] >> (w.slot_bits + q * w.digit)) & dmask)];
    }
  }
  return w;
}

// for_blocks of the threaded sorts with the blocks in reverse order: the result must not depend
// on which block runs first.
auto reverseBlocks(int blocks) {
  return [blocks](const auto& fn) {
    for (int b = blocks - 1; b >= 0; --b) fn(b);
  };
}

}  // namespace

TEST(RadixSort, TopDownSortGivesTheLsdOrder) {
  std::vector<std::uint32_t> counts;
  // radixSortTopDown() (the voxel filter's sort of large scans) against radixScatter() on packed
  // key << slot | slot words, slots in order: keys of 2-4 digits, clustered (buckets of every
  // size: insertion, 8-bit passes, digits shared by a whole bucket) and spread, many duplicates.
  std::mt19937_64 rng(11);
  std::vector<std::uint64_t> tmp, tmp2;
  for (int key_bits : {20, 31, 35, 41}) {
    for (int spread : {0, 1}) {
      const std::uint64_t kmask = (std::uint64_t{1} << key_bits) - 1;
      // clustered: few distinct high bits, low bits from a small range (duplicates)
      const PackedWords pw = packedWords(key_bits, 200000, [&](int) {
        return spread ? rng() & kmask
                      : ((rng() % 7) << (key_bits - 3) | (rng() % 300) << 4 | (rng() % 3)) & kmask;
      });
      const int slot_bits = pw.slot_bits, passes = pw.passes, digit = pw.digit;
      const std::uint32_t dmask = (1u << digit) - 1;
      const std::vector<std::uint64_t>& words = pw.words;
      const std::vector<std::uint32_t>& hist = pw.hist;
      std::vector<std::uint64_t> want = words, got = words;
      std::vector<std::uint32_t> h1 = hist, h2 = hist;
      gf::radixScatter<std::uint32_t>(slot_bits, passes, digit, h1.data(), &want, &tmp, nullptr,
                                      nullptr);
      // declines (nothing changed) when a bucket is too large
      const std::uint32_t* top = hist.data() + (static_cast<std::size_t>(passes - 1) << digit);
      const std::size_t largest = *std::max_element(top, top + dmask + 1);
      EXPECT_FALSE(
          gf::radixSortTopDown(slot_bits, passes, digit, h2.data(), &got, &tmp2, largest - 1));
      EXPECT_EQ(got, words);
      EXPECT_EQ(h2, hist);
      ASSERT_TRUE(gf::radixSortTopDown(slot_bits, passes, digit, h2.data(), &got, &tmp2, largest));
      ASSERT_TRUE(std::is_sorted(want.begin(), want.end()));
      EXPECT_EQ(got, want) << "key bits " << key_bits << ", spread " << spread;
      // The buckets split into ranges (the voxel filter's threads), run in any order.
      for (int blocks : {2, 3, 7}) {
        got = words;
        h2 = hist;
        ASSERT_TRUE(gf::radixSortTopDown(slot_bits, passes, digit, h2.data(), &got, &tmp2, largest,
                                         blocks, &counts, reverseBlocks(blocks)));
        EXPECT_EQ(got, want) << "key bits " << key_bits << ", spread " << spread << ", blocks "
                             << blocks;
      }
    }
  }
}

TEST(RadixSort, BlockScatterGivesTheSerialOrder) {
  // radixScatterBlocks() (the voxel filter's LSD sort on several threads) against radixScatter()
  // on packed key << slot | slot words: blocks run in reverse order, 1-7 blocks (sizes that do
  // not divide n), a digit shared by every key (its pass skipped), many duplicates.
  std::mt19937_64 rng(12);
  std::vector<std::uint64_t> tmp;
  std::vector<std::uint32_t> counts;
  for (int key_bits : {20, 31, 35}) {
    for (int narrow : {0, 1}) {
      const std::uint64_t kmask = (std::uint64_t{1} << key_bits) - 1;
      // narrow: the top digit is 0 for every key
      PackedWords pw = packedWords(key_bits, 100003, [&](int digit) {
        return narrow ? rng() % (std::uint64_t{1} << digit) : rng() & kmask;
      });
      const int slot_bits = pw.slot_bits, passes = pw.passes, digit = pw.digit;
      const std::vector<std::uint64_t>& words = pw.words;
      std::vector<std::uint64_t> want = words;
      gf::radixScatter<std::uint32_t>(slot_bits, passes, digit, pw.hist.data(), &want, &tmp,
                                      nullptr, nullptr);
      ASSERT_TRUE(std::is_sorted(want.begin(), want.end()));
      for (int blocks : {1, 2, 3, 7}) {
        std::vector<std::uint64_t> got = words;
        gf::radixScatterBlocks<std::uint32_t>(slot_bits, passes, digit, blocks, &got, &tmp, nullptr,
                                              nullptr, &counts, reverseBlocks(blocks));
        EXPECT_EQ(got, want) << "key bits " << key_bits << ", narrow " << narrow << ", blocks "
                             << blocks;
      }
    }
  }
}

TEST(RadixSort, ThreadedSortGivesTheSerialOrder) {
  // Above the packed words' limit (kRadixPackedMaxPoints), so the per-thread blocks, and within
  // it (packed words in blocks: a KITTI frame's sorts); 1, 2 and 3 threads must give
  // std::stable_sort's order and the keys in it: narrow keys with many duplicates, one-pass and
  // three-pass widths, a constant key (every pass skipped) and tile keys (x << 32 | y).
  std::mt19937_64 rng(5);
  gf::RadixSortScratch scratch;
  std::vector<std::uint32_t> order;
  for (const std::size_t n : {gf::kRadixPackedMaxPoints + 17, 3 * gf::kRadixPointsPerThread + 5})
    for (int kind = 0; kind < 5; ++kind) {
      std::vector<std::uint64_t> keys(n);
      for (auto& k : keys) {
        const std::uint64_t r = rng();
        k = kind == 0   ? r % 7
            : kind == 1 ? r & 0x3fffff
            : kind == 2 ? r & ((std::uint64_t{1} << 45) - 1)
            : kind == 3 ? 12345
                        : ((r % 40) << 32) | ((r >> 20) % 40);
      }
      std::vector<std::uint32_t> want(n);
      for (std::size_t i = 0; i < n; ++i) want[i] = static_cast<std::uint32_t>(i);
      std::stable_sort(want.begin(), want.end(),
                       [&](std::uint32_t a, std::uint32_t b) { return keys[a] < keys[b]; });
      for (int threads : {1, 2, 3}) {
        order.assign(5, 7);  // stale contents must not matter
        gf::radixSortByKey(keys, &order, &scratch, threads);
        EXPECT_EQ(order, want) << "n " << n << ", kind " << kind << ", threads " << threads;
        bool keys_follow = scratch.keys.size() == n;
        for (std::size_t j = 0; keys_follow && j < n; ++j)
          keys_follow = scratch.keys[j] == keys[want[j]];
        EXPECT_TRUE(keys_follow) << "n " << n << ", kind " << kind << ", threads " << threads;
      }
    }
}

namespace {

/// VmFlags of the /proc/self/smaps mapping that holds `p` ("" when not found).
std::string vmFlagsOf(const void* p) {
  std::ifstream smaps("/proc/self/smaps");
  const auto a = reinterpret_cast<std::uintptr_t>(p);
  bool inside = false;
  for (std::string line; std::getline(smaps, line);) {
    unsigned long lo = 0, hi = 0;
    if (std::sscanf(line.c_str(), "%lx-%lx ", &lo, &hi) == 2 && line.find(':') > 8) {
      inside = a >= lo && a < hi;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      return line;
    }
  }
  return "";
}

}  // namespace

TEST(HugePages, LargeScratchBuffersAreAdvisedSmallOnesUntouched) {
  // Resizes keep working for every size; a buffer that grows past kHugeBufferMinBytes is
  // reallocated and madvise(MADV_HUGEPAGE)d (VmFlags "hg") before it is filled.
  std::vector<std::uint64_t> small(10, 7), large;
  gf::resizeScratch(&small, 1000);
  EXPECT_EQ(small.size(), 1000u);
  EXPECT_EQ(small[0], 7u);  // below the size: a plain resize keeps the contents
  const std::size_t n = 2 * gf::kHugeBufferMinBytes / sizeof(std::uint64_t);
  gf::resizeScratch(&large, n);
  ASSERT_EQ(large.size(), n);
  const std::uint64_t* block = large.data();
  gf::resizeScratch(&large, n / 2);  // shrinking keeps the block
  EXPECT_EQ(large.size(), n / 2);
  EXPECT_EQ(large.data(), block);
#if defined(__linux__)
  std::ifstream thp("/sys/kernel/mm/transparent_hugepage/enabled");
  if (!thp) GTEST_SKIP() << "no transparent huge pages in this kernel";
  const std::string flags = vmFlagsOf(large.data() + n / 4);
  ASSERT_FALSE(flags.empty()) << "mapping not found in /proc/self/smaps";
  EXPECT_NE(flags.find(" hg"), std::string::npos) << flags;
  EXPECT_EQ(vmFlagsOf(small.data()).find(" hg"), std::string::npos);
#endif
}

// ---------------------------------------------------------------------- local ground plane

namespace {

// K nearest neighbours of every point by brute force (ties by lower index), rows of k entries.
std::vector<std::int32_t> bruteKnn(const Cloud& c, int k) {
  const std::size_t n = c.size() / 3;
  std::vector<std::int32_t> rows(n * k);
  std::vector<std::pair<float, std::int32_t>> d(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      const float dx = c[3 * j] - c[3 * i], dy = c[3 * j + 1] - c[3 * i + 1],
                  dz = c[3 * j + 2] - c[3 * i + 2];
      d[j] = {dx * dx + dy * dy + dz * dz, static_cast<std::int32_t>(j)};
    }
    std::partial_sort(d.begin(), d.begin() + k, d.end());
    for (int e = 0; e < k; ++e) rows[i * k + e] = d[e].second;
  }
  return rows;
}

}  // namespace

TEST(NormalLocalGround, VergeSlopingAwayFromTheTilePlaneIsGroundABushOnItIsNot) {
  // The stage alone (every point sampled), on the labels a road tile's plane leaves: a road at
  // z = 0 for x < 1 and a verge falling away from it at 25 % (14 deg, inside the plane window)
  // for x >= 1, labelled ground except the strip x [1.6, 2.0) that the road plane misses (more
  // than plane_distance under it). A bush on the verge, 0.3 to 1 m over it, non-ground; and two
  // test points above the verge at 0.08 m (over the band above) and under it at 0.08 m.
  auto verge_z = [](double x) { return x < 1.0 ? 0.0 : -0.25 * (x - 1.0); };
  Cloud c;
  std::vector<std::uint8_t> ground;
  std::vector<std::size_t> strip, bush;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 30; ++j) {
      const double x = 0.05 + 0.1 * i, y = 0.05 + 0.1 * j;
      const bool missed = x >= 1.6 && x < 2.0;
      if (missed) strip.push_back(c.size() / 3);
      add(&c, x, y, verge_z(x));
      ground.push_back(!missed);
    }
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int b = 0; b < 150; ++b) {  // 0.6 m across at x 2.5, y 1.5
    const double x = 2.2 + 0.6 * u(rng), y = 1.2 + 0.6 * u(rng);
    bush.push_back(c.size() / 3);
    add(&c, x, y, verge_z(x) + 0.3 + 0.7 * u(rng));
    ground.push_back(0);
  }
  const std::size_t over = c.size() / 3;
  add(&c, 3.02, 0.52, verge_z(3.02) + 0.08 / std::cos(std::atan(0.25)));
  ground.push_back(0);
  const std::size_t under = c.size() / 3;
  add(&c, 3.02, 2.52, verge_z(3.02) - 0.08 / std::cos(std::atan(0.25)));
  ground.push_back(0);

  const gf::NormalGroundFilterParams p;  // the defaults: 8 ground neighbours, 0.10 / 0.05 m
  const int k = 40;
  const std::vector<std::int32_t> rows = bruteKnn(c, k);
  const double min_abs_nz = std::cos(15.0 * M_PI / 180.0);
  std::vector<std::uint8_t> out = ground;
  gf::normal::LocalGroundStage stage;
  const std::size_t added =
      stage.run(c, rows.data(), nullptr, c.size() / 3, k, nullptr, p.local_ground_min,
                p.local_ground_below, p.local_ground_above, min_abs_nz, 2, &out);
  std::size_t strip_ground = 0, bush_ground = 0;
  for (std::size_t i : strip) strip_ground += out[i];
  for (std::size_t i : bush) bush_ground += out[i];
  EXPECT_EQ(strip_ground, strip.size());
  EXPECT_EQ(bush_ground, 0u);
  EXPECT_EQ(out[over], 0);   // 0.08 m over the verge: an object's base may be there
  EXPECT_EQ(out[under], 1);  // 0.08 m under it: nothing stands under the ground
  EXPECT_EQ(added, strip.size() + 1);
  // Ground stays ground; with more ground neighbours needed than a list holds, nothing changes.
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (ground[i]) ASSERT_EQ(out[i], 1) << i;
  }
  std::vector<std::uint8_t> none = ground;
  EXPECT_EQ(stage.run(c, rows.data(), nullptr, c.size() / 3, k, nullptr, k + 1,
                      p.local_ground_below, p.local_ground_above, min_abs_nz, 2, &none),
            0u);
  EXPECT_EQ(none, ground);
  // A wider band above takes the point over the verge.
  std::vector<std::uint8_t> wide = ground;
  stage.run(c, rows.data(), nullptr, c.size() / 3, k, nullptr, p.local_ground_min, 0.10, 0.10,
            min_abs_nz, 2, &wide);
  EXPECT_EQ(wide[over], 1);
}

TEST(NormalLocalGround, OnlyAddsGroundAndZeroTurnsItOff) {
  // The whole filter on a generated street: the stage only turns non-ground points into ground.
  gf::SceneParams sp;
  sp.seed = 1;
  const gf::GeneratedScan scan = gf::generateScene(sp);
  gf::NormalGroundFilterParams on;
  on.scan_type = "ground";
  gf::NormalGroundFilterParams off = on;
  off.local_ground_min = 0;
  const auto view = gf::CloudView::packedXyz(scan.xyz.data(), scan.size());
  std::vector<std::uint8_t> with, plain;
  gf::NormalGroundFilter(on).filter(view, &with);
  gf::NormalGroundFilter(off).filter(view, &plain);
  ASSERT_EQ(with.size(), scan.size());
  std::size_t added = 0;
  for (std::size_t i = 0; i < with.size(); ++i) {
    if (plain[i] == gf::kGround) ASSERT_EQ(with[i], gf::kGround) << i;
    added += with[i] != plain[i];
  }
  EXPECT_GT(added, 0u);
}

// A small robot's 16-beam sensor (builtin lidar16: rings 2 deg apart, 0.2 deg a firing): with
// the default stride each K neighbourhood lies on one scan line, almost no point is a candidate
// and the ground is lost. Either rule widens the stride until the neighbourhoods reach the next
// line: max_line_ratio from the measured lines before the normals (common/scan_lines.h),
// min_candidate_share after them (normal::sparseLinesStride()).
TEST(NormalGroundFilter, SparseScanLinesWidenTheStride) {
  struct Rules {
    double line_ratio, share;
    const char* note;  // what FilterStats::note says ("" = nothing about the stride)
  };
  const Rules rules[] = {{0.0, 0.0, ""},
                         {3.0, 0.0, "scan lines 2.00 deg apart, 0.200 deg between"},
                         {0.0, 0.05, "under min_candidate_share"}};
  for (std::uint32_t seed : {1u, 2u}) {
    gf::SceneParams sp = gf::builtinSceneParams("lidar16");
    sp.seed = seed;
    const gf::GeneratedScan scan = gf::generateScene(sp);
    const gf::CloudView view = gf::CloudView::packedXyz(scan.xyz.data(), scan.size());
    const std::vector<std::int8_t> truth(scan.truth.begin(), scan.truth.end());
    for (int stride : {1, 2}) {  // (3 already reaches the next line here)
      for (const Rules& r : rules) {
        gf::NormalGroundFilterParams p;  // the defaults (scan_type auto), as a user runs it
        p.sample_stride = stride;
        p.max_line_ratio = r.line_ratio;
        p.min_candidate_share = r.share;
        gf::NormalGroundFilter f(p);
        std::vector<std::uint8_t> labels;
        gf::FilterStats st;
        f.filter(view, &labels, &st);
        const double f1 = gf::computeMetrics(gf::countConfusion(labels, truth)).f1;
        std::printf(
            "[ SPARSE   ] seed %u stride %d, max_line_ratio %g, min_candidate_share %g: "
            "F1 %.4f (%s)\n",
            seed, stride, r.line_ratio, r.share, f1, st.note.c_str());
        if (*r.note == 0) {
          EXPECT_LT(f1, 0.6) << "seed " << seed << " stride " << stride;
          EXPECT_EQ(st.note.find("sample_stride"), std::string::npos) << st.note;
        } else {
          EXPECT_GE(f1, 0.9) << "seed " << seed << " stride " << stride << " " << r.note;
          EXPECT_NE(st.note.find("sample_stride " + std::to_string(stride) + " -> 4"),
                    std::string::npos)
              << st.note;
          EXPECT_NE(st.note.find(r.note), std::string::npos) << st.note;
        }
      }
    }
  }
}

TEST(NormalGroundFilter, SparseLinesStrideDoublesUpToTheLargest) {
  using gf::normal::sparseLinesStride;
  EXPECT_EQ(sparseLinesStride(40, 1000, 0.05, 2), 4);  // 4 % candidates: twice the stride
  EXPECT_EQ(sparseLinesStride(50, 1000, 0.05, 2), 0);  // 5 %: kept
  EXPECT_EQ(sparseLinesStride(0, 1000, 0.0, 2), 0);    // rule off
  EXPECT_EQ(sparseLinesStride(0, 999, 0.05, 2), 0);    // too few sampled points to judge
  EXPECT_EQ(sparseLinesStride(0, 1000, 0.05, 1), 2);
  EXPECT_EQ(sparseLinesStride(0, 1000, 0.05, 12), 16);  // capped at sample_stride's largest
  EXPECT_EQ(sparseLinesStride(0, 1000, 0.05, 16), 0);
}

namespace {

// F1 of `labels` against `truth` (ground positive).
double f1Of(const std::vector<std::uint8_t>& labels, const std::vector<std::uint8_t>& truth) {
  std::size_t tp = 0, fp = 0, fn = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    tp += labels[i] == 1 && truth[i] == 1;
    fp += labels[i] == 1 && truth[i] == 0;
    fn += labels[i] != 1 && truth[i] == 1;
  }
  return 2.0 * tp / (2.0 * tp + fp + fn);
}

// x, y of packed `xyz` rounded to steps of qx, qy (coordinates stored coarsely).
std::vector<float> onLattice(std::vector<float> xyz, double qx, double qy) {
  for (std::size_t i = 0; i < xyz.size(); i += 3) {
    xyz[i] = static_cast<float>(std::round(xyz[i] / qx) * qx);
    xyz[i + 1] = static_cast<float>(std::round(xyz[i + 1] / qy) * qy);
  }
  return xyz;
}

}  // namespace

// The lattice of each axis: float32 steps of a UTM easting / northing (1/16 m, 0.5 m) found
// exactly; natural coordinates, steps below 1 cm and clouds too small to judge give none.
TEST(NormalLattice, StepsOfQuantisedAxesNoneForNaturalOnes) {
  const gf::GeneratedScan scan = gf::generateScene(gf::builtinSceneParams("lidar"));
  gf::normal::LatticeMeter meter;
  double step[3];
  EXPECT_FALSE(meter.measure(gf::CloudView::packedXyz(scan.xyz.data(), scan.size()), step));
  EXPECT_EQ(step[0], 0.0);
  const std::vector<float> utm = onLattice(scan.xyz, 0.0625, 0.5);
  EXPECT_TRUE(meter.measure(gf::CloudView::packedXyz(utm.data(), scan.size()), step));
  EXPECT_EQ(step[0], 0.0625);
  EXPECT_EQ(step[1], 0.5);
  EXPECT_EQ(step[2], 0.0);
  const std::vector<float> fine = onLattice(scan.xyz, 0.005, 0.005);
  EXPECT_FALSE(meter.measure(gf::CloudView::packedXyz(fine.data(), scan.size()), step));
  EXPECT_FALSE(meter.measure(gf::CloudView::packedXyz(utm.data(), 40), step));  // 40 points
}

// A registered street stored as float32 at a UTM northing (y in 0.5 m steps): the dense
// cloud's neighbours share one y and, without the lattice's variance, flat ground had its
// smallest eigenvector along y (F1 89.85 against 97.76 at the origin, the street as PCD).
TEST(NormalGroundFilter, CoarseLatticeKeepsTheGround) {
  const gf::GeneratedScan scan = gf::generateScene(gf::builtinSceneParams("mls"));
  gf::NormalGroundFilterParams p;
  p.threads = 2;
  p.scan_type = "registered";
  gf::NormalGroundFilter filter(p);
  std::vector<std::uint8_t> labels;
  filter.filter(gf::CloudView::packedXyz(scan.xyz.data(), scan.size()), &labels);
  const double natural = f1Of(labels, scan.truth);
  ASSERT_GT(natural, 0.95);
  const std::vector<float> utm = onLattice(scan.xyz, 0.0625, 0.5);
  gf::FilterStats stats;
  filter.filter(gf::CloudView::packedXyz(utm.data(), scan.size()), &labels, &stats);
  EXPECT_GT(f1Of(labels, scan.truth), natural - 0.005) << natural;
  EXPECT_NE(stats.note.find("0.0625 / 0.5 / 0 m lattice"), std::string::npos) << stats.note;
}
