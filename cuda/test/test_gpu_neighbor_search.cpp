// GPU tests of the NeighborSearch adapter, the factory and the normal-vector filter on the GPU
// backend (run on a machine with a CUDA GPU; the CPU-only fallback test is test/test_gpu_fallback).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "brute_force_knn.h"
#include "gpu_neighbor_search.h"
#include "gpu_test.h"
#include "ground_filter/cuda_knn.h"
#include "ground_filter/neighbor_search.h"
#include "ground_filter/normal_ground_filter.h"
#include "knn/kdtree_neighbor_search.h"
#include "knn/neighborhood_pca.h"

namespace gf = ground_filter;

namespace {

/// The GPU search's fallback, as the factory gives it.
std::unique_ptr<gf::KnnBackend> kdTree() { return std::make_unique<gf::KdTreeNeighborSearch>(0); }

std::vector<float> kittiFrame() {
  auto xyz = gf_test::readKittiBin(std::string(GF_DATA_DIR) + "/000000.bin");
  EXPECT_GT(xyz.size(), 3u * 100000) << "missing " << GF_DATA_DIR << "/000000.bin";
  return xyz;
}

/// Rows of a and b are equal except where a tie at the K-th distance let the kd-tree keep another
/// point: then distances still agree slot by slot. Returns the number of rows differing in indices.
std::size_t compareWithKdTree(const gf::NeighborLists& gpu, const gf::NeighborLists& cpu) {
  EXPECT_EQ(gpu.k, cpu.k);
  EXPECT_EQ(gpu.points, cpu.points);
  std::size_t rows_differ = 0;
  for (std::size_t i = 0; i < gpu.points; ++i) {
    bool differ = false;
    for (int j = 0; j < gpu.k; ++j) {
      const std::size_t e = i * gpu.k + j;
      EXPECT_EQ(gpu.sq_dists[e], cpu.sq_dists[e]) << "row " << i << " slot " << j;
      if (gpu.sq_dists[e] != cpu.sq_dists[e]) return gpu.points;
      differ |= gpu.indices[e] != cpu.indices[e];
    }
    rows_differ += differ;
  }
  return rows_differ;
}

using GpuNeighborSearchTest = gf_test::GpuTest;

TEST_F(GpuNeighborSearchTest, FactoryGivesTheGpuBackend) {
  EXPECT_TRUE(gf::neighborSearchAvailable("gpu"));
  std::string note = "stale";
  auto s = gf::makeNeighborSearch("gpu", 0, &note);
  EXPECT_EQ(s->name(), "gpu");
  EXPECT_TRUE(note.empty()) << note;
}

TEST_F(GpuNeighborSearchTest, KittiListsEqualTheKdTreesAndBruteForce) {
  const auto xyz = kittiFrame();
  const std::size_t n = xyz.size() / 3;
  gf::GpuNeighborSearch gpu(kdTree());
  gf::KdTreeNeighborSearch cpu;
  gf::NeighborLists a, b;
  gpu.search(xyz.data(), n, 50, &a);
  EXPECT_EQ(gpu.lastBackend(), "gpu");
  EXPECT_TRUE(gpu.lastNote().empty()) << gpu.lastNote();
  cpu.search(xyz.data(), n, 50, &b);
  const std::size_t differ = compareWithKdTree(a, b);
  // Only K-th-distance ties may differ (the GPU keeps the lowest index among them).
  EXPECT_LT(differ, n / 1000) << differ << " of " << n << " rows differ";
  std::printf("[ KITTI    ] GPU vs kd-tree: %zu of %zu rows differ in indices (K-th ties only)\n",
              differ, n);
  std::string first;
  EXPECT_EQ(gf_test::compareRows(xyz.data(), n, 50, a.indices.data(), a.sq_dists.data(),
                                 {0, 1, 1000, 50000, n - 1}, &first),
            0u)
      << first;
}

TEST_F(GpuNeighborSearchTest, CudaFailureFallsBackToKdTreeForThatScan) {
  const auto xyz = kittiFrame();
  const std::size_t n = xyz.size() / 3;
  gf::CudaKnnOptions opt;
  opt.memory_limit = 1 << 20;  // the GPU cannot take this scan
  gf::GpuNeighborSearch gpu(kdTree(), opt);
  gf::NeighborLists a, b;
  gpu.search(xyz.data(), n, 50, &a);
  EXPECT_EQ(gpu.name(), "gpu");
  EXPECT_EQ(gpu.lastBackend(), "kdtree");
  EXPECT_NE(gpu.lastNote().find("cudaErrorMemoryAllocation"), std::string::npos) << gpu.lastNote();
  gf::KdTreeNeighborSearch cpu;
  cpu.search(xyz.data(), n, 50, &b);
  EXPECT_EQ(a.indices, b.indices);
  EXPECT_EQ(a.sq_dists, b.sq_dists);
  // The next (small) scan runs on the GPU again.
  std::vector<float> small(xyz.begin(), xyz.begin() + 3 * 300);
  gpu.search(small.data(), 300, 8, &a);
  EXPECT_EQ(gpu.lastBackend(), "gpu");
  EXPECT_TRUE(gpu.lastNote().empty()) << gpu.lastNote();
  std::string first;
  EXPECT_EQ(
      gf_test::compareRows(small.data(), 300, 8, a.indices.data(), a.sq_dists.data(), {}, &first),
      0u)
      << first;
}

TEST_F(GpuNeighborSearchTest, KAboveTheGpuLimitRunsOnTheKdTree) {
  const auto xyz = kittiFrame();
  std::vector<float> part(xyz.begin(), xyz.begin() + 3 * 20000);
  gf::GpuNeighborSearch gpu(kdTree());
  gf::NeighborLists a;
  gpu.search(part.data(), 20000, 100, &a);
  EXPECT_EQ(gpu.lastBackend(), "kdtree");
  EXPECT_NE(gpu.lastNote().find("k <= 64"), std::string::npos) << gpu.lastNote();
  EXPECT_EQ(a.k, 100);
  std::string first;
  EXPECT_EQ(gf_test::compareRows(part.data(), 20000, 100, a.indices.data(), a.sq_dists.data(),
                                 {0, 10, 19999}, &first),
            0u)
      << first;
}

TEST_F(GpuNeighborSearchTest, EmptyAndTinyClouds) {
  gf::GpuNeighborSearch gpu(kdTree());
  gf::NeighborLists a;
  gpu.search(nullptr, 0, 50, &a);
  EXPECT_EQ(a.points, 0u);
  EXPECT_TRUE(a.indices.empty());
  const std::vector<float> three = {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 2.f, 0.f};
  gpu.search(three.data(), 3, 50, &a);
  EXPECT_EQ(gpu.lastBackend(), "gpu");
  ASSERT_EQ(a.indices.size(), 150u);
  EXPECT_EQ(a.indices[0], 0);
  EXPECT_EQ(a.indices[1], 1);
  EXPECT_EQ(a.indices[2], 2);
  EXPECT_EQ(a.indices[3], -1);
  EXPECT_EQ(a.sq_dists[3], std::numeric_limits<float>::infinity());
}

TEST_F(GpuNeighborSearchTest, ListsOnDeviceGiveTheCpuPcaAndCounts) {
  const auto xyz = kittiFrame();
  const std::size_t n = xyz.size() / 3;
  gf::GpuNeighborSearch gpu(kdTree());
  EXPECT_TRUE(gpu.keepLists(true));
  gf::NeighborLists dev, host;
  gpu.search(xyz.data(), n, 50, &dev);
  EXPECT_EQ(gpu.lastBackend(), "gpu");
  EXPECT_EQ(dev.points, n);
  EXPECT_TRUE(dev.indices.empty());  // nothing came back
  std::vector<gf::PointPca> pg, pc;
  ASSERT_TRUE(gpu.neighborhoodPca(&pg));
  gf::KdTreeNeighborSearch cpu;
  cpu.search(xyz.data(), n, 50, &host);
  gf::computeNeighborhoodPca(xyz.data(), host, 0, &pc);
  ASSERT_EQ(pg.size(), n);
  std::size_t valid_differ = 0, bit_equal = 0, far = 0, valid = 0;
  double max_eig = 0.0, max_angle = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (pg[i].valid != pc[i].valid) {
      ++valid_differ;
      continue;
    }
    if (!pg[i].valid) continue;
    ++valid;
    bool same = true;
    const double a[3] = {pg[i].normal[0], pg[i].normal[1], pg[i].normal[2]};
    const double b[3] = {pc[i].normal[0], pc[i].normal[1], pc[i].normal[2]};
    for (int c = 0; c < 3; ++c) {
      same &= pg[i].normal[c] == pc[i].normal[c] && pg[i].eigen[c] == pc[i].eigen[c];
      max_eig = std::max(max_eig, std::abs(double(pg[i].eigen[c]) - pc[i].eigen[c]));
    }
    bit_equal += same;
    // Angle between the (sign-free) normals; atan2 of |a x b| and |a . b| stays exact near 0.
    const double cx = a[1] * b[2] - a[2] * b[1], cy = a[2] * b[0] - a[0] * b[2],
                 cz = a[0] * b[1] - a[1] * b[0];
    const double angle = std::atan2(std::sqrt(cx * cx + cy * cy + cz * cz),
                                    std::abs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]));
    max_angle = std::max(max_angle, angle);
    far += angle > 1e-4;
  }
  EXPECT_EQ(valid_differ, 0u);
  EXPECT_LT(max_eig, 1e-5);
  EXPECT_LT(far, n / 10000 + 1) << "normals more than 1e-4 rad apart";
  std::printf(
      "[ PCA      ] GPU vs CPU on KITTI: %zu valid, %zu bit-identical, max |d eigen| %.2e, "
      "max normal angle %.2e rad\n",
      valid, bit_equal, max_eig, max_angle);

  std::vector<std::uint8_t> flags(n);
  for (std::size_t i = 0; i < n; ++i) flags[i] = (i * 2654435761u) % 5 < 2;
  std::vector<std::uint16_t> flagged(n), size(n);
  ASSERT_TRUE(gpu.countFlaggedNeighbors(flags.data(), flagged.data(), size.data()));
  std::size_t bad = 0;
  for (std::size_t i = 0; i < n; ++i) {
    int u = 0, m = 0;
    for (; m < 50 && host.indices[i * 50 + m] >= 0; ++m) u += flags[host.indices[i * 50 + m]];
    bad += flagged[i] != u || size[i] != m;
  }
  EXPECT_EQ(bad, 0u);
}

TEST_F(GpuNeighborSearchTest, CudaFailureAfterTheSearchRedoesTheScanOnTheKdTree) {
  const auto xyz = kittiFrame();
  const std::size_t n = xyz.size() / 3;
  gf::GpuNeighborSearch probe(kdTree());
  probe.keepLists(true);
  gf::NeighborLists lists;
  probe.search(xyz.data(), n, 50, &lists);
  // Room for the search, none for the PCA results.
  gf::CudaKnnOptions opt;
  opt.memory_limit = probe.cudaKnn().deviceBytes() + 1024;
  gf::GpuNeighborSearch gpu(kdTree(), opt);
  gpu.keepLists(true);
  gpu.search(xyz.data(), n, 50, &lists);
  EXPECT_EQ(gpu.lastBackend(), "gpu") << gpu.lastNote();
  EXPECT_TRUE(lists.indices.empty());
  std::vector<gf::PointPca> pca;
  EXPECT_FALSE(gpu.neighborhoodPca(&pca));
  EXPECT_EQ(gpu.lastBackend(), "kdtree");
  EXPECT_NE(gpu.lastNote().find("GPU PCA failed (cudaErrorMemoryAllocation"), std::string::npos)
      << gpu.lastNote();
  gf::NeighborLists ref;
  gf::KdTreeNeighborSearch cpu;
  cpu.search(xyz.data(), n, 50, &ref);
  EXPECT_EQ(lists.indices, ref.indices);  // the scan's lists are now on the host
  std::vector<std::uint16_t> a(n), b(n);
  std::vector<std::uint8_t> flags(n, 1);
  EXPECT_FALSE(gpu.countFlaggedNeighbors(flags.data(), a.data(), b.data()));
}

TEST_F(GpuNeighborSearchTest, NormalFilterOnGpuMatchesKdTreeAndCompactsNaN) {
  auto xyz = kittiFrame();
  // Every 97th point NaN/Inf: the filter compacts them away before the search.
  std::size_t invalid = 0;
  for (std::size_t i = 0; i < xyz.size() / 3; i += 97, ++invalid) {
    xyz[3 * i + (i % 3)] =
        (i % 2) ? std::numeric_limits<float>::quiet_NaN() : std::numeric_limits<float>::infinity();
  }
  const auto cloud = gf::CloudView::packedXyz(xyz.data(), xyz.size() / 3);
  gf::NormalGroundFilterParams pg, pc;
  pg.knn_backend = "gpu";
  pc.knn_backend = "kdtree";
  gf::NormalGroundFilter fg(pg), fc(pc);
  EXPECT_EQ(fg.backend(), "gpu");
  EXPECT_TRUE(fg.backendNote().empty()) << fg.backendNote();
  std::vector<std::uint8_t> lg, lc;
  gf::FilterStats sg, sc;
  fg.filter(cloud, &lg, &sg);
  fc.filter(cloud, &lc, &sc);
  EXPECT_EQ(sg.backend, "gpu");
  EXPECT_TRUE(sg.note.empty()) << sg.note;
  EXPECT_EQ(sg.invalid_points, invalid);
  ASSERT_EQ(lg.size(), lc.size());
  std::size_t differ = 0, ground = 0;
  for (std::size_t i = 0; i < lg.size(); ++i) {
    differ += lg[i] != lc[i];
    ground += lg[i];
  }
  EXPECT_GT(ground, lg.size() / 4);
  EXPECT_LT(differ, lg.size() / 1000) << differ << " labels differ";
  std::printf(
      "[ FILTER   ] GPU vs kd-tree labels: %zu of %zu differ; ground %zu; GPU total "
      "%.2f ms, kd-tree total %.2f ms\n",
      differ, lg.size(), ground, sg.total_ms, sc.total_ms);
}

}  // namespace
