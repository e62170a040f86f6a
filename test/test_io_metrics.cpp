// Loader, writer and metric tests against hand-computed numbers (the ground_filter_eval CLI
// contract is in test_eval_cli.cpp). Nothing here depends on a filter's accuracy.

#include <gtest/gtest.h>

#include <algorithm>

#include "io_test_util.h"

namespace {

using namespace gf_io_test;  // NOLINT: the shared test helpers

// ------------------------------------------------------------------ metrics

TEST(Metrics, CountConfusionByHand) {
  const std::vector<std::uint8_t> labels = {1, 1, 0, 0, 1, 0, 1, 0};
  const std::vector<std::int8_t> truth = {1, 0, 0, 1, -1, -1, 1, 5};
  const gf::Confusion c = gf::countConfusion(labels, truth);
  EXPECT_EQ(c.tp, 2u);  // indices 0, 6
  EXPECT_EQ(c.fp, 1u);  // index 1
  EXPECT_EQ(c.tn, 1u);  // index 2
  EXPECT_EQ(c.fn, 1u);  // index 3; 4, 5 (-1) and 7 (unknown value) are ignored
  EXPECT_EQ(c.total(), 5u);
}

TEST(Metrics, SizeMismatchThrows) {
  EXPECT_THROW(gf::countConfusion({1, 0}, {1}), std::invalid_argument);
  EXPECT_NO_THROW(gf::countConfusion({}, {}));
}

TEST(Metrics, ComputeByHand) {
  gf::Confusion c;
  c.tp = 3;
  c.fp = 1;
  c.tn = 4;
  c.fn = 2;
  const gf::Metrics m = gf::computeMetrics(c);
  EXPECT_DOUBLE_EQ(m.accuracy, 0.7);    // 7 / 10
  EXPECT_DOUBLE_EQ(m.precision, 0.75);  // 3 / 4
  EXPECT_DOUBLE_EQ(m.recall, 0.6);      // 3 / 5
  EXPECT_DOUBLE_EQ(m.f1, 2.0 / 3.0);    // 2 * 0.75 * 0.6 / 1.35
  EXPECT_DOUBLE_EQ(m.iou, 0.5);         // 3 / 6
  EXPECT_NEAR(m.f1, 2 * m.precision * m.recall / (m.precision + m.recall), 1e-12);
}

TEST(Metrics, ZeroDenominatorsAreNaN) {
  const gf::Metrics empty = gf::computeMetrics(gf::Confusion());
  EXPECT_TRUE(std::isnan(empty.accuracy));
  EXPECT_TRUE(std::isnan(empty.precision));
  EXPECT_TRUE(std::isnan(empty.recall));
  EXPECT_TRUE(std::isnan(empty.f1));
  EXPECT_TRUE(std::isnan(empty.iou));

  gf::Confusion no_ground;  // no ground in truth, none predicted
  no_ground.tn = 5;
  const gf::Metrics a = gf::computeMetrics(no_ground);
  EXPECT_DOUBLE_EQ(a.accuracy, 1.0);
  EXPECT_TRUE(std::isnan(a.precision));
  EXPECT_TRUE(std::isnan(a.recall));
  EXPECT_TRUE(std::isnan(a.f1));
  EXPECT_TRUE(std::isnan(a.iou));

  gf::Confusion missed;  // ground exists, nothing predicted ground
  missed.tn = 3;
  missed.fn = 2;
  const gf::Metrics b = gf::computeMetrics(missed);
  EXPECT_DOUBLE_EQ(b.accuracy, 0.6);
  EXPECT_TRUE(std::isnan(b.precision));
  EXPECT_DOUBLE_EQ(b.recall, 0.0);
  EXPECT_DOUBLE_EQ(b.f1, 0.0);
  EXPECT_DOUBLE_EQ(b.iou, 0.0);
}

TEST(Metrics, PoolingAddsCounts) {
  gf::Confusion a, b;
  a.tp = 90;
  a.fn = 10;  // file a: recall 0.9
  b.tp = 1;
  b.fp = 1;
  b.tn = 8;  // file b: precision 0.5
  gf::Confusion pooled = a;
  pooled.add(b);
  EXPECT_EQ(pooled.tp, 91u);
  EXPECT_EQ(pooled.fp, 1u);
  EXPECT_EQ(pooled.tn, 8u);
  EXPECT_EQ(pooled.fn, 10u);
  const gf::Metrics m = gf::computeMetrics(pooled);
  EXPECT_DOUBLE_EQ(m.precision, 91.0 / 92.0);
  EXPECT_DOUBLE_EQ(m.recall, 91.0 / 101.0);
  EXPECT_DOUBLE_EQ(m.f1, 182.0 / 193.0);
  EXPECT_DOUBLE_EQ(m.accuracy, 99.0 / 110.0);
}

// ------------------------------------------------------------------ protocols

TEST(Protocols, SemanticKitti) {
  EXPECT_EQ(gf::semanticKittiTruth(0, -2.f), -1);  // unlabeled
  EXPECT_EQ(gf::semanticKittiTruth(1, -2.f), -1);  // outlier
  for (std::uint32_t cls : {40u, 44u, 48u, 49u, 60u, 72u}) {
    EXPECT_EQ(gf::semanticKittiTruth(cls, 5.f), 1) << cls;  // ground classes at any height
  }
  EXPECT_EQ(gf::semanticKittiTruth(70, -1.30f), 1);  // vegetation below -1.2975 m
  EXPECT_EQ(gf::semanticKittiTruth(70, -1.29f), 0);  // vegetation above it
  EXPECT_EQ(gf::semanticKittiTruth(70, 0.5f), 0);
  EXPECT_EQ(gf::semanticKittiTruth(10, -1.7f), 0);              // car
  EXPECT_EQ(gf::semanticKittiTruth(50, -1.7f), 0);              // building
  EXPECT_EQ(gf::semanticKittiTruth(71, -1.7f), 0);              // trunk
  EXPECT_EQ(gf::semanticKittiTruth((7u << 16) | 40u, 0.f), 1);  // instance id in the high bits
  EXPECT_EQ(gf::semanticKittiTruth((3u << 16) | 1u, 0.f), -1);
  EXPECT_EQ(gf::semanticKittiTruth((3u << 16) | 10u, 0.f), 0);
}

TEST(Protocols, Isprs) {
  EXPECT_EQ(gf::isprsTruth(1), 1);
  EXPECT_EQ(gf::isprsTruth(0), 0);
  EXPECT_EQ(gf::isprsTruth(255), -1);
  EXPECT_EQ(gf::isprsTruth(2), -1);
  EXPECT_EQ(gf::isprsTruth(0.5), -1);
}

// ------------------------------------------------------------------ KITTI .bin

TEST(LoadScan, KittiBinWithLabels) {
  TempDir tmp;
  const std::vector<KittiPoint> pts = {
      {1.f, 2.f, -1.7f, 0.25f, 40},              // road -> 1
      {3.f, -4.f, -1.5f, 0.5f, 70},              // vegetation, low -> 1
      {3.5f, -4.f, -1.0f, 0.75f, 70},            // vegetation, high -> 0
      {0.f, 0.f, 0.f, 0.f, 0},                   // unlabeled -> -1
      {9.f, 9.f, 9.f, 1.f, 1},                   // outlier -> -1
      {-2.f, 1.f, -0.5f, 0.125f, 10},            // car -> 0
      {-2.f, 1.f, 2.f, 0.f, (12u << 16) | 48u},  // sidewalk (instance bits) -> 1
      {5.f, 5.f, -1.8f, 0.f, 72},                // terrain -> 1
  };
  const std::string bin = tmp / "000007.bin";
  writeKitti(bin, pts, true);

  const gf::Scan scan = gf::loadScan(bin);
  EXPECT_EQ(scan.path, bin);
  ASSERT_EQ(scan.size(), pts.size());
  EXPECT_EQ(scan.cloud.point_step, 16u);
  EXPECT_EQ(scan.cloud.height, 1u);
  EXPECT_TRUE(hasField(scan.cloud, "intensity"));
  const gf::CloudView view = gf::viewOf(scan.cloud);
  ASSERT_EQ(view.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_EQ(view.x(i), pts[i].x);
    EXPECT_EQ(view.y(i), pts[i].y);
    EXPECT_EQ(view.z(i), pts[i].z);
    EXPECT_EQ(fieldValue<float>(scan.cloud, "intensity", i), pts[i].intensity);
  }
  const std::vector<std::int8_t> expected = {1, 1, 0, -1, -1, 0, 1, 1};
  EXPECT_EQ(scan.truth, expected);
}

TEST(LoadScan, KittiBinWithoutLabelsAndVelodyneLayout) {
  TempDir tmp;
  const std::vector<KittiPoint> pts = {{1.f, 2.f, -1.7f, 0.f, 40}, {1.f, 2.f, 1.f, 0.f, 50}};
  writeKitti(tmp / "a.bin", pts, false);
  const gf::Scan a = gf::loadScan(tmp / "a.bin");
  EXPECT_EQ(a.size(), 2u);
  EXPECT_FALSE(a.labelled());

  // SemanticKITTI layout: sequences/00/velodyne/000000.bin + labels/000000.label
  fs::create_directories(tmp / "velodyne");
  fs::create_directories(tmp / "labels");
  writeKitti(tmp / "velodyne/000000.bin", pts, true);
  fs::rename(tmp / "velodyne/000000.label", tmp / "labels/000000.label");
  const gf::Scan b = gf::loadScan(tmp / "velodyne/000000.bin");
  EXPECT_EQ(b.truth, (std::vector<std::int8_t>{1, 0}));
}

TEST(LoadScan, KittiErrors) {
  TempDir tmp;
  // missing file
  try {
    gf::loadScan(tmp / "missing.bin");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.bin"), std::string::npos) << e.what();
  }
  // size not a multiple of 16 B
  const float junk[5] = {1, 2, 3, 4, 5};
  writeBytes(tmp / "bad.bin", junk, sizeof(junk));
  EXPECT_THROW(gf::loadScan(tmp / "bad.bin"), std::runtime_error);
  // label count mismatch: 3 points, 2 labels
  const float xyzi[12] = {0};
  writeBytes(tmp / "mm.bin", xyzi, sizeof(xyzi));
  const std::uint32_t labels[2] = {40, 40};
  writeBytes(tmp / "mm.label", labels, sizeof(labels));
  try {
    gf::loadScan(tmp / "mm.bin");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("label count mismatch"), std::string::npos) << e.what();
  }
  // unknown extension; a directory is not a scan
  writeText(tmp / "x.xyz", "1 2 3\n");
  EXPECT_THROW(gf::loadScan(tmp / "x.xyz"), std::runtime_error);
  EXPECT_THROW(gf::loadScan(tmp.str()), std::runtime_error);
}

// ------------------------------------------------------------------ PCD / PLY

TEST(LoadScan, PcdAnyLayoutWithIsprsLabels) {
  TempDir tmp;
  // x is not first, an extra double field, label as uint32 (0, 1, 255, 2 -> 0, 1, -1, -1).
  writeText(tmp / "t.pcd",
            "# .PCD v0.7\nVERSION 0.7\nFIELDS intensity x y z t label\nSIZE 4 4 4 4 8 4\n"
            "TYPE F F F F F U\nCOUNT 1 1 1 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
            "POINTS 4\nDATA ascii\n"
            "0.5 1 2 3 100.25 0\n"
            "0.25 -1 -2 -3 200.5 1\n"
            "0 10 20 30 0 255\n"
            "1 4 5 6 1 2\n");
  const gf::Scan scan = gf::loadScan(tmp / "t.pcd");
  EXPECT_EQ(xyzOf(scan), (std::vector<float>{1, 2, 3, -1, -2, -3, 10, 20, 30, 4, 5, 6}));
  EXPECT_EQ(fieldValue<float>(scan.cloud, "intensity", 0), 0.5f);
  EXPECT_EQ(fieldValue<double>(scan.cloud, "t", 1), 200.5);
  EXPECT_EQ(scan.truth, (std::vector<std::int8_t>{0, 1, -1, -1}));
}

TEST(LoadScan, PcdWithoutLabelAndBadXyz) {
  TempDir tmp;
  writeText(tmp / "nolabel.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n1 2 3\n4 5 6\n");
  const gf::Scan a = gf::loadScan(tmp / "nolabel.pcd");
  EXPECT_EQ(a.size(), 2u);
  EXPECT_FALSE(a.labelled());

  writeText(tmp / "noz.pcd",
            "VERSION 0.7\nFIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1\nWIDTH 1\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n1 2\n");
  const gf::Scan b = gf::loadScan(tmp / "noz.pcd");
  try {
    gf::viewOf(b.cloud);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'z'"), std::string::npos) << e.what();
  }

  writeText(tmp / "dbl.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n1 2 3\n");
  {  // float64 x/y/z (survey exports) are read as float32, the other fields kept
    const gf::Scan d = gf::loadScan(tmp / "dbl.pcd");
    const gf::CloudView v = gf::viewOf(d.cloud);
    ASSERT_EQ(v.size(), 1u);
    EXPECT_EQ(v.x(0), 1.0f);
    EXPECT_EQ(v.y(0), 2.0f);
    EXPECT_EQ(v.z(0), 3.0f);
    EXPECT_EQ(d.shift[0], 0.0);  // near the origin: read as they are
  }
  writeText(tmp / "utm.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n627000.123 4842000.456 100.789\n"
            "627010.5 4842020.25 101.5\n");
  {  // float64 in projected coordinates: moved onto the middle in double, millimetres kept
    const gf::Scan d = gf::loadScan(tmp / "utm.pcd");
    EXPECT_EQ(d.shift[0], 627005.0);
    EXPECT_EQ(d.shift[1], 4842010.0);
    EXPECT_EQ(d.shift[2], 101.0);
    const gf::CloudView v = gf::viewOf(d.cloud);
    ASSERT_EQ(v.size(), 2u);
    EXPECT_NEAR(v.x(0), -4.877, 1e-5);
    EXPECT_NEAR(v.y(0), -9.544, 1e-5);
    EXPECT_NEAR(v.z(0), -0.211, 1e-5);
    EXPECT_NEAR(v.y(1), 10.25, 1e-5);
  }
  writeText(
      tmp / "garbage64.pcd",
      "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n1e300 2e300 3e300\n1e300 2e300 3e300\n");
  EXPECT_EQ(gf::loadScan(tmp / "garbage64.pcd").shift[0], 0.0);  // no map: not moved
  {  // keep_float64 (scene_publisher): the doubles stay as they are, the nodelets move them
    const gf::Scan d = gf::loadScan(tmp / "utm.pcd", /*keep_float64=*/true);
    EXPECT_EQ(d.shift[0], 0.0);
    ASSERT_EQ(d.cloud.fields[1].datatype, pcl::PCLPointField::FLOAT64);
    double y;
    std::memcpy(&y, d.cloud.data.data() + d.cloud.fields[1].offset, sizeof y);
    EXPECT_EQ(y, 4842000.456);
    EXPECT_THROW(gf::viewOf(d.cloud), std::runtime_error);
  }
  writeText(tmp / "mixed.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 8 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n1 2 3\n");
  EXPECT_THROW(gf::viewOf(gf::loadScan(tmp / "mixed.pcd").cloud), std::runtime_error);

  writeText(tmp / "garbage.pcd", "this is not a point cloud\n");
  EXPECT_THROW(gf::loadScan(tmp / "garbage.pcd"), std::runtime_error);  // PCL alone crashes here
  writeText(tmp / "short.pcd",
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3\n");
  EXPECT_THROW(gf::loadScan(tmp / "short.pcd"), std::runtime_error);  // fewer points than POINTS
}

TEST(LoadScan, PlyAscii) {
  TempDir tmp;
  writeText(tmp / "t.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nproperty float intensity\nend_header\n"
            "1 2 3 0.5\n-4 5.5 -6 0.25\n7 8 9 1\n");
  const gf::Scan scan = gf::loadScan(tmp / "t.ply");
  EXPECT_EQ(xyzOf(scan), (std::vector<float>{1, 2, 3, -4, 5.5f, -6, 7, 8, 9}));
  EXPECT_EQ(fieldValue<float>(scan.cloud, "intensity", 1), 0.25f);
  EXPECT_FALSE(scan.labelled());

  writeText(tmp / "garbage.ply", "this is not a point cloud\n");
  EXPECT_THROW(gf::loadScan(tmp / "garbage.ply"), std::runtime_error);
  writeText(tmp / "short.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nend_header\n1 2 3\n");
  EXPECT_THROW(gf::loadScan(tmp / "short.ply"), std::runtime_error);
}

// ------------------------------------------------------------------ listing, stems, writers

TEST(ListScanFiles, SortedScanFilesOnly) {
  TempDir tmp;
  for (const char* name : {"c.ply", "a.bin", "b.pcd", "a.label", "notes.txt"}) {
    writeText(tmp / name, "x");
  }
  fs::create_directories(tmp / "sub.pcd");  // a directory is not a scan file
  const std::vector<std::string> files = gf::listScanFiles(tmp.str());
  EXPECT_EQ(files, (std::vector<std::string>{tmp / "a.bin", tmp / "b.pcd", tmp / "c.ply"}));
  EXPECT_EQ(gf::listScanFiles(tmp / "b.pcd"), (std::vector<std::string>{tmp / "b.pcd"}));
  EXPECT_EQ(gf::listScanFiles("builtin:lidar:3"), (std::vector<std::string>{"builtin:lidar:3"}));
  EXPECT_THROW(gf::listScanFiles(tmp / "nope"), std::runtime_error);
}

TEST(Writers, StemAndLabels) {
  EXPECT_EQ(gf::scanStem("/a/b/000001.bin"), "000001");
  EXPECT_EQ(gf::scanStem("samp11.pcd"), "samp11");
  EXPECT_EQ(gf::scanStem("builtin:lidar:7"), "builtin_lidar_7");
  EXPECT_EQ(gf::scanStem("builtin:lidar:7:beams=32,sensor_height=1"),
            "builtin_lidar_7_beams-32_sensor_height-1");
  TempDir tmp;
  const std::vector<std::uint8_t> labels = {1, 0, 0, 1, 1};
  const std::string out = gf::writeLabels(tmp / "out/labels", "/x/000003.bin", labels);
  EXPECT_EQ(out, tmp / "out/labels/000003.gnd");
  const std::vector<char> bytes = readBytes(out);
  EXPECT_EQ(std::vector<std::uint8_t>(bytes.begin(), bytes.end()), labels);
}

TEST(Writers, SplitCloudsKeepEveryField) {
  TempDir tmp;
  // Records of 24 B: x y z (float) | 2 B padding | ring (uint16) | intensity (float) | 4 B pad.
  pcl::PCLPointCloud2 c;
  auto field = [](const char* name, std::uint32_t off, std::uint8_t type) {
    return pcl::PCLPointField{name, off, type, 1};
  };
  c.fields = {field("x", 0, pcl::PCLPointField::FLOAT32),
              field("y", 4, pcl::PCLPointField::FLOAT32),
              field("z", 8, pcl::PCLPointField::FLOAT32),
              field("intensity", 16, pcl::PCLPointField::FLOAT32),
              field("ring", 14, pcl::PCLPointField::UINT16)};
  const std::size_t n = 5;
  c.width = n;
  c.height = 1;
  c.point_step = 24;
  c.row_step = 24 * n;
  c.data.assign(24 * n, 0xAB);
  for (std::size_t i = 0; i < n; ++i) {
    const float xyz[3] = {float(i), float(10 * i), float(-1.0 * i)};
    const std::uint16_t ring = static_cast<std::uint16_t>(100 + i);
    const float intensity = 0.5f * i;
    std::memcpy(&c.data[24 * i], xyz, 12);
    std::memcpy(&c.data[24 * i + 14], &ring, 2);
    std::memcpy(&c.data[24 * i + 16], &intensity, 4);
  }
  const std::vector<std::uint8_t> labels = {1, 0, 1, 1, 0};
  EXPECT_THROW(gf::writeSplitClouds(tmp.str(), "f.pcd", c, {1, 0}), std::runtime_error);
  const auto paths = gf::writeSplitClouds(tmp / "clouds", "/data/f.pcd", c, labels);
  EXPECT_EQ(paths.first, tmp / "clouds/f_ground.pcd");
  EXPECT_EQ(paths.second, tmp / "clouds/f_nonground.pcd");

  const gf::Scan g = gf::loadScan(paths.first);
  const gf::Scan ng = gf::loadScan(paths.second);
  ASSERT_EQ(g.size(), 3u);
  ASSERT_EQ(ng.size(), 2u);
  const std::vector<std::size_t> g_idx = {0, 2, 3}, ng_idx = {1, 4};
  for (std::size_t k = 0; k < g_idx.size(); ++k) {
    const std::size_t i = g_idx[k];
    EXPECT_EQ(fieldValue<float>(g.cloud, "x", k), float(i));
    EXPECT_EQ(fieldValue<float>(g.cloud, "y", k), float(10 * i));
    EXPECT_EQ(fieldValue<float>(g.cloud, "z", k), float(-1.0 * i));
    EXPECT_EQ(fieldValue<std::uint16_t>(g.cloud, "ring", k), 100 + i);
    EXPECT_EQ(fieldValue<float>(g.cloud, "intensity", k), 0.5f * i);
  }
  for (std::size_t k = 0; k < ng_idx.size(); ++k) {
    const std::size_t i = ng_idx[k];
    EXPECT_EQ(fieldValue<float>(ng.cloud, "x", k), float(i));
    EXPECT_EQ(fieldValue<std::uint16_t>(ng.cloud, "ring", k), 100 + i);
    EXPECT_EQ(fieldValue<float>(ng.cloud, "intensity", k), 0.5f * i);
  }
  // The binary PCD header says binary.
  const std::vector<char> bytes = readBytes(paths.first);
  EXPECT_NE(std::string(bytes.begin(), bytes.end()).find("DATA binary\n"), std::string::npos);

  // All ground: the non-ground file is a valid empty cloud.
  const auto all = gf::writeSplitClouds(tmp / "all", "f.pcd", c, std::vector<std::uint8_t>(n, 1));
  EXPECT_EQ(gf::loadScan(all.first).size(), n);
  EXPECT_EQ(gf::loadScan(all.second).size(), 0u);
}

// ------------------------------------------------------------------ real data

TEST(RealData, SemanticKittiGroundShares) {
  GF_SKIP_WITHOUT_DATA(dataDir() + "/semantickitti/seq00");
  const struct {
    const char* file;
    double share;
  } frames[] = {{"000000", 0.605}, {"000001", 0.599}, {"000002", 0.592}};
  for (const auto& f : frames) {
    const std::string path = dataDir() + "/semantickitti/seq00/" + f.file + ".bin";
    const gf::Scan scan = gf::loadScan(path);
    const std::size_t expected_points = fs::file_size(path) / 16;
    EXPECT_EQ(scan.size(), expected_points);
    EXPECT_GT(scan.size(), 120000u);
    EXPECT_LT(scan.size(), 130000u);
    ASSERT_TRUE(scan.labelled()) << path;
    EXPECT_EQ(scan.truth.size(), scan.size());
    // The data README's shares are rounded to 0.1 %.
    EXPECT_NEAR(groundShare(scan.truth), f.share, 0.0005) << path;
  }
}

TEST(RealData, KittiFrameCountsByClass) {
  GF_SKIP_WITHOUT_DATA(dataDir() + "/semantickitti/seq00/000000.bin");
  // 000000: 124,668 points; the count of ignored points is what the protocol leaves out.
  const gf::Scan scan = gf::loadScan(dataDir() + "/semantickitti/seq00/000000.bin");
  EXPECT_EQ(scan.size(), 124668u);
  std::size_t ignored = 0;
  for (const auto t : scan.truth) ignored += t < 0;
  EXPECT_LT(ignored, scan.size() / 10);  // a few percent unlabeled/outlier, not most of the scan
}

TEST(RealData, IsprsSamp11) {
  GF_SKIP_WITHOUT_DATA(dataDir() + "/isprs/samp11.pcd");
  const gf::Scan scan = gf::loadScan(dataDir() + "/isprs/samp11.pcd");
  EXPECT_EQ(scan.size(), 38010u);
  ASSERT_TRUE(scan.labelled());
  EXPECT_NEAR(groundShare(scan.truth), 0.57, 0.005);
  EXPECT_EQ(gf::viewOf(scan.cloud).size(), 38010u);
}

TEST(RealData, Os128Organised) {
  GF_SKIP_WITHOUT_DATA(dataDir() + "/unlabelled/os128_000000.pcd");
  const gf::Scan scan = gf::loadScan(dataDir() + "/unlabelled/os128_000000.pcd");
  EXPECT_EQ(scan.cloud.height, 128u);
  EXPECT_EQ(scan.cloud.width, 1875u);
  EXPECT_EQ(gf::viewOf(scan.cloud).size(), 240000u);
  EXPECT_TRUE(hasField(scan.cloud, "ring"));
  EXPECT_TRUE(hasField(scan.cloud, "timestamp"));
  EXPECT_FALSE(scan.labelled());
}

// ------------------------------------------------------------------ built-in scenes

TEST(Builtin, LidarSceneHasTruthAndFields) {
  const gf::Scan a = gf::loadScan("builtin:lidar:5");
  ASSERT_GT(a.size(), 10000u);
  ASSERT_EQ(a.truth.size(), a.size());
  EXPECT_TRUE(hasField(a.cloud, "intensity"));
  EXPECT_TRUE(hasField(a.cloud, "ring"));
  const double share = groundShare(a.truth);
  EXPECT_GT(share, 0.05);  // a street scene: both classes present
  EXPECT_LT(share, 0.95);
  const gf::Scan b = gf::loadScan("builtin:lidar:5");
  EXPECT_EQ(a.cloud.data, b.cloud.data);  // deterministic
  EXPECT_EQ(a.truth, b.truth);
  EXPECT_THROW(gf::loadScan("builtin:moon"), std::runtime_error);
  EXPECT_THROW(gf::loadScan("builtin:lidar:abc"), std::runtime_error);
}

// --write-scans: a generated scene (with NaN points and low vegetation, whose class alone would
// read as ground under SemanticKITTI's rule) written as KITTI files reads back as the same scan.
TEST(Writers, KittiScanReadsBackAsTheSameTruth) {
  const std::string spec = "builtin:lidar16:2:layout=offroad,sensor_height=1.8,nan_points=50";
  const gf::Scan a = gf::loadScan(spec);
  TempDir tmp;
  const std::string bin = gf::writeKittiScan(tmp / "k", a);
  EXPECT_EQ(bin, tmp / "k/builtin_lidar16_2_layout-offroad_sensor_height-1.8_nan_points-50.bin");
  const gf::Scan b = gf::loadScan(bin);
  ASSERT_EQ(b.size(), a.size());
  EXPECT_EQ(b.truth, a.truth);
  const gf::CloudView va = gf::viewOf(a.cloud), vb = gf::viewOf(b.cloud);
  std::size_t finite = 0, kept_class = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    float x, y, z, u, v, w;
    const bool fa = va.get(i, &x, &y, &z), fb = vb.get(i, &u, &v, &w);
    ASSERT_EQ(fa, fb) << i;
    if (!fa) continue;
    ++finite;
    EXPECT_TRUE(x == u && y == v && z == w) << i;
    // A class is renamed only where it would read as another truth (low vegetation: 99).
    const bool reads_same = gf::semanticKittiTruth(a.semantic[i], z) == a.truth[i];
    EXPECT_EQ(b.semantic[i], reads_same ? a.semantic[i] : a.truth[i] ? 49 : 99) << i;
    kept_class += a.semantic[i] == b.semantic[i];
  }
  EXPECT_EQ(a.size() - finite, 50u);
  EXPECT_GT(kept_class, finite / 2);
  EXPECT_LT(kept_class, finite);  // low vegetation is in this scene
  EXPECT_THROW(gf::writeKittiScan(tmp / "k", b), std::runtime_error);  // the scan itself
}

// ------------------------------------------------------------------ per-class counts

TEST(Metrics, ClassCountsByHand) {
  const std::vector<std::uint8_t> labels = {1, 0, 1, 1, 0, 1, 1};
  const std::vector<std::int8_t> truth = {1, 1, 1, 0, 0, -1, 1};
  const std::vector<std::uint16_t> cls = {40, 40, 70, 70, 50, 40, 40};
  std::vector<gf::ClassCount> table;
  gf::addClassCounts(labels, truth, cls, &table);
  ASSERT_EQ(table.size(), 4u);  // (40, g) (50, ng) (70, ng) (70, g); the ignored point left out
  EXPECT_EQ(table[0].cls, 40);
  EXPECT_EQ(table[0].truth, 1);
  EXPECT_EQ(table[0].points, 3u);
  EXPECT_EQ(table[0].labelled_ground, 2u);
  EXPECT_EQ(table[1].cls, 50);
  EXPECT_EQ(table[1].labelled_ground, 0u);
  EXPECT_EQ(table[2].cls, 70);
  EXPECT_EQ(table[2].truth, 0);
  EXPECT_EQ(table[2].labelled_ground, 1u);
  EXPECT_EQ(table[3].cls, 70);
  EXPECT_EQ(table[3].truth, 1);
  gf::addClassCounts(labels, truth, cls, &table);  // pooling: same groups, doubled
  ASSERT_EQ(table.size(), 4u);
  EXPECT_EQ(table[0].points, 6u);
  EXPECT_EQ(table[0].labelled_ground, 4u);
  EXPECT_THROW(gf::addClassCounts(labels, truth, {40}, &table), std::invalid_argument);
  EXPECT_EQ(gf::semanticKittiClassName(72), "terrain");
  EXPECT_EQ(gf::semanticKittiClassName(999), "class 999");
}

TEST(LoadScan, KittiClassesKept) {
  TempDir tmp;
  const std::vector<KittiPoint> pts = smallScene();
  writeKitti(tmp / "c.bin", pts, true);
  const gf::Scan scan = gf::loadScan(tmp / "c.bin");
  ASSERT_EQ(scan.semantic.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) ASSERT_EQ(scan.semantic[i], pts[i].label & 0xFFFF);
  writeKitti(tmp / "d.bin", pts, false);
  EXPECT_TRUE(gf::loadScan(tmp / "d.bin").semantic.empty());
}

TEST(Builtin, FailureModeScenesHaveClassesAndTruth) {
  for (const char* kind : {"verge", "offroad", "trail"}) {
    const std::string path = std::string("builtin:") + kind + ":2";
    const gf::Scan s = gf::loadScan(path);
    ASSERT_GT(s.size(), 20000u) << path;
    ASSERT_EQ(s.semantic.size(), s.size()) << path;
    ASSERT_EQ(s.truth.size(), s.size()) << path;
    std::size_t vegetation = 0, terrain = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (s.semantic[i] == 70) {
        ++vegetation;
        ASSERT_EQ(s.truth[i], 0) << path;  // bushes: never ground, any height
      }
      if (s.semantic[i] == 72) {
        ++terrain;
        ASSERT_EQ(s.truth[i], 1) << path;
      }
    }
    EXPECT_GT(vegetation, 1000u) << path;
    EXPECT_GT(terrain, 5000u) << path;
  }
  const std::vector<std::string> kinds = gf::builtinSceneKinds();
  EXPECT_EQ(kinds.size(), 17u);
  EXPECT_NE(std::find(kinds.begin(), kinds.end(), "profiler"), kinds.end());
  try {
    gf::loadScan("builtin:moon");
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("offroad"), std::string::npos) << e.what();
  }
}

}  // namespace
