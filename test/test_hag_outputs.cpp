// The clouds of the height-above-ground outputs (src/nodelets/hag_outputs.h) without a ROS graph:
// the float field written during the copies, the surface cloud, the obstacle band, bad input (no
// ground, NaN, a point below the surface).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "gf_test_clouds.h"
#include "hag_outputs.h"

namespace gf = ground_filter;
using sensor_msgs::PointCloud2;
using sensor_msgs::PointField;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

float floatAt(const PointCloud2& c, std::size_t i, std::size_t offset) {
  float v;
  std::memcpy(&v, c.data.data() + i * c.point_step + offset, sizeof(float));
  return v;
}

// What `plain` (unpadded rows) with a float32 field appended holding values[k] for its k-th
// record must be: each record whole, zeros up to the next multiple of 4, the value.
PointCloud2 widened(const PointCloud2& plain, const std::vector<float>& values) {
  PointCloud2 out = plain;
  const std::size_t in_step = plain.point_step, offset = (in_step + 3) / 4 * 4;
  const std::size_t n = std::size_t{plain.width} * plain.height;
  out.point_step = static_cast<std::uint32_t>(offset + 4);
  out.row_step = out.point_step * plain.width;
  out.fields.push_back(gf_test::field(gf::kHeightFieldName, static_cast<std::uint32_t>(offset),
                                      PointField::FLOAT32));
  out.data.assign(n * out.point_step, 0);
  for (std::size_t k = 0; k < n; ++k) {
    std::memcpy(&out.data[k * out.point_step], &plain.data[k * in_step], in_step);
    std::memcpy(&out.data[k * out.point_step + offset], &values.at(k), sizeof(float));
  }
  return out;
}

// 14-byte records: x, y, z (f32), id (u16: the point index); rows padded by `row_pad` bytes.
struct Scene {
  std::vector<float> xyz;
  std::vector<std::uint8_t> labels;
  void add(float x, float y, float z, std::uint8_t label) {
    xyz.insert(xyz.end(), {x, y, z});
    labels.push_back(label);
  }
  std::size_t size() const { return labels.size(); }
  PointCloud2 cloud(std::uint32_t height = 1, std::uint32_t row_pad = 0) const {
    const std::uint32_t w = static_cast<std::uint32_t>(size() / height);
    return gf_test::buildCloud(
        {gf_test::field("x", 0, PointField::FLOAT32), gf_test::field("y", 4, PointField::FLOAT32),
         gf_test::field("z", 8, PointField::FLOAT32), gf_test::field("id", 12, PointField::UINT16)},
        14, w, height, row_pad, 0xEE, 1, [&](std::uint8_t* rec, std::uint32_t i) {
          std::memcpy(rec, &xyz[3 * i], 12);
          const std::uint16_t id = static_cast<std::uint16_t>(i);
          std::memcpy(rec + 12, &id, 2);
        });
  }
};

// A flat 10 m x 10 m ground (z 0, 0.25 m grid), a post (1 point every 0.1 m up to 3 m) at
// (5.1, 5.1), a ditch point 0.4 m below the ground, a NaN point.
Scene postScene() {
  Scene s;
  for (float y = 0.05f; y < 10.f; y += 0.25f) {
    for (float x = 0.05f; x < 10.f; x += 0.25f) s.add(x, y, 0.f, gf::kGround);
  }
  for (float z = 0.05f; z < 3.f; z += 0.1f) s.add(5.1f, 5.1f, z, gf::kNonGround);
  s.add(2.2f, 7.7f, -0.4f, gf::kNonGround);
  s.add(kNaN, 1.f, 1.f, gf::kNonGround);
  while (s.size() % 4) s.add(1.f, 1.f, 0.f, gf::kGround);  // 4 rows in cloud(4, ...)
  return s;
}

}  // namespace

TEST(HagOutputs, ObstacleBandKeepsWholeRecordsInTheBand) {
  const Scene s = postScene();
  for (const std::uint32_t pad : {0u, 7u}) {
    const PointCloud2 in = s.cloud(4, pad);
    gf::CloudLayout layout;
    ASSERT_EQ(gf::checkPointCloud2(in, &layout, nullptr), gf::CloudRejectReason::kNone);
    gf::GroundSurface surface;
    surface.build(gf::CloudView::packedXyz(s.xyz.data(), s.size()), s.labels,
                  gf::GroundSurfaceParams());
    std::vector<float> h;
    surface.heights(gf::CloudView::packedXyz(s.xyz.data(), s.size()), &h);
    PointCloud2 obs, with_field;
    gf::ObstacleBand band;  // 0.2 .. 2.5 m
    EXPECT_TRUE(gf::makeObstacleCloud(in, layout, s.labels, h, band, &obs));
    // ~hag_field: the same records, each with its height, written as it is copied (into a
    // reused message's old bytes).
    with_field.data.assign(4 * in.data.size(), 0xAB);
    std::string why;
    EXPECT_TRUE(gf::makeObstacleCloud(in, layout, s.labels, h, band, &with_field,
                                      gf::kHeightFieldName, &why))
        << why;
    std::vector<float> kept;
    EXPECT_EQ(obs.header.frame_id, in.header.frame_id);
    EXPECT_EQ(obs.point_step, 14u);
    EXPECT_EQ(obs.height, 1u);
    std::size_t want = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      want += s.labels[i] == gf::kNonGround && h[i] >= 0.2f && h[i] <= 2.5f;
    }
    EXPECT_EQ(want, 23u);  // the post from 0.25 to 2.45 m
    ASSERT_EQ(obs.width, want);
    for (std::size_t k = 0; k < obs.width; ++k) {
      std::uint16_t id;
      std::memcpy(&id, &obs.data[k * 14 + 12], 2);
      EXPECT_NEAR(floatAt(obs, k, 8), s.xyz[3 * id + 2], 0.f);  // the record of point `id`
      EXPECT_GE(h[id], 0.2f);
      kept.push_back(h[id]);
    }
    EXPECT_EQ(with_field.fields.size(), 5u);
    EXPECT_EQ(with_field.data, widened(obs, kept).data);  // records, zeroed gaps, heights
    EXPECT_EQ(with_field.point_step, 20u);
    EXPECT_EQ(with_field.row_step, 20u * obs.width);
    // The ditch point lies below the surface: a negative height, never an obstacle.
    std::size_t ditch = 0;
    while (s.xyz[3 * ditch + 2] != -0.4f) ++ditch;
    EXPECT_NEAR(h[ditch], -0.4f, 1e-3f);
  }
}

TEST(HagOutputs, NoGroundGivesNanHeightsEmptySurfaceNoObstacles) {
  Scene s = postScene();
  s.labels.assign(s.size(), gf::kNonGround);
  const PointCloud2 in = s.cloud();
  gf::CloudLayout layout;
  ASSERT_EQ(gf::checkPointCloud2(in, &layout, nullptr), gf::CloudRejectReason::kNone);
  gf::GroundSurface surface;
  const gf::CloudView view = gf::CloudView::packedXyz(s.xyz.data(), s.size());
  surface.build(view, s.labels, gf::GroundSurfaceParams());
  std::vector<float> h;
  surface.heights(view, &h);
  for (const float x : h) ASSERT_TRUE(std::isnan(x));
  PointCloud2 obs, surf;
  gf::makeObstacleCloud(in, layout, s.labels, h, gf::ObstacleBand(), &obs);
  EXPECT_EQ(obs.width, 0u);
  EXPECT_TRUE(obs.data.empty());
  gf::makeSurfaceCloud(surface, in.header, &surf);
  EXPECT_EQ(surf.width, 0u);
  EXPECT_EQ(surf.fields.size(), 5u);
}

TEST(HagOutputs, SurfaceCloudOnePointPerCell) {
  const Scene s = postScene();
  gf::GroundSurface surface;
  surface.build(gf::CloudView::packedXyz(s.xyz.data(), s.size()), s.labels,
                gf::GroundSurfaceParams());
  std_msgs::Header header;
  header.frame_id = "base_link";
  PointCloud2 surf;
  gf::makeSurfaceCloud(surface, header, &surf);
  ASSERT_EQ(surf.width, surface.cells().size());
  EXPECT_EQ(surf.width, 100u);  // 10 x 10 cells of 1 m
  EXPECT_EQ(surf.header.frame_id, "base_link");
  const char* names[] = {"x", "y", "z", "points", "confidence"};
  for (int f = 0; f < 5; ++f) EXPECT_EQ(surf.fields[f].name, names[f]);
  EXPECT_EQ(surf.fields[3].datatype, PointField::UINT32);
  for (std::size_t k = 0; k < surf.width; ++k) {
    const gf::SurfaceCell& c = surface.cells()[k];
    EXPECT_EQ(floatAt(surf, k, 0), c.x);
    EXPECT_EQ(floatAt(surf, k, 8), c.z);
    std::uint32_t n;
    std::memcpy(&n, &surf.data[k * 20 + 12], 4);
    EXPECT_EQ(n, c.points);
    EXPECT_GT(floatAt(surf, k, 16), 0.f);
  }
}

// A surface built on points moved near the origin (a map in projected coordinates,
// CloudProcessingBuffers::shift) goes out where the points are: float64 x/y/z for a float64
// input, the shift added back in double.
TEST(HagOutputs, SurfaceCloudOfMovedPointsIsMovedBack) {
  const Scene s = postScene();
  gf::GroundSurface surface;
  surface.build(gf::CloudView::packedXyz(s.xyz.data(), s.size()), s.labels,
                gf::GroundSurfaceParams());
  const double shift[3] = {627031.0, 4842017.0, 213.0};
  PointCloud2 wide, narrow;
  gf::makeSurfaceCloud(surface, std_msgs::Header(), &wide, shift, true);
  gf::makeSurfaceCloud(surface, std_msgs::Header(), &narrow, shift, false);
  ASSERT_EQ(wide.width, surface.cells().size());
  ASSERT_EQ(narrow.width, surface.cells().size());
  EXPECT_EQ(wide.point_step, 32u);
  EXPECT_EQ(narrow.point_step, 20u);
  for (int f = 0; f < 3; ++f) {
    EXPECT_EQ(wide.fields[f].datatype, PointField::FLOAT64);
    EXPECT_EQ(wide.fields[f].offset, 8u * f);
    EXPECT_EQ(narrow.fields[f].datatype, PointField::FLOAT32);
  }
  EXPECT_EQ(wide.fields[3].offset, 24u);
  EXPECT_EQ(wide.fields[4].offset, 28u);
  for (std::size_t k = 0; k < wide.width; ++k) {
    const gf::SurfaceCell& c = surface.cells()[k];
    double xyz[3];
    std::memcpy(xyz, &wide.data[k * 32], sizeof(xyz));
    EXPECT_EQ(xyz[0], c.x + shift[0]);  // in double: the cell centre to the bit
    EXPECT_EQ(xyz[1], c.y + shift[1]);
    EXPECT_EQ(xyz[2], c.z + shift[2]);
    std::uint32_t n;
    std::memcpy(&n, &wide.data[k * 32 + 24], 4);
    EXPECT_EQ(n, c.points);
    EXPECT_EQ(floatAt(narrow, k, 4), static_cast<float>(c.y + shift[1]));
  }
}

// ~ground, ~nonground and ~labeled get the heights while their records are copied; the bytes are
// those of the plain copy with each record widened by its height.
TEST(HagOutputs, SplitAndLabeledCarryTheFieldAsTheyCopy) {
  const Scene s = postScene();
  std::vector<float> v(s.size());
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = 0.25f * static_cast<float>(i) - 3.f;
  gf::RecordFloatField field;
  field.name = gf::kHeightFieldName;
  field.values = &v;
  for (const std::uint32_t pad : {0u, 7u}) {
    const PointCloud2 in = s.cloud(4, pad);
    gf::CloudLayout layout;
    ASSERT_EQ(gf::checkPointCloud2(in, &layout, nullptr), gf::CloudRejectReason::kNone);
    std::vector<std::uint8_t> labels = s.labels;
    const gf::SplitCounts counts = gf::finalizeLabels(in, layout, &labels);
    EXPECT_EQ(counts.invalid, 1u);
    // Reused (pooled) messages hold old bytes: every byte must be written, the gaps too.
    PointCloud2 g, ng, ref_g, ref_ng;
    g.data.assign(2 * in.data.size(), 0xAB);
    ng.data = g.data;
    std::string why;
    ASSERT_TRUE(gf::copySplit(in, layout, labels, counts, &g, &ng, &field, &why)) << why;
    std::vector<std::uint8_t> ref_labels = s.labels;
    gf::splitPointCloud2(in, layout, &ref_labels, &ref_g, &ref_ng);
    ASSERT_EQ(ref_labels, labels);
    std::vector<float> vg, vng;
    for (std::size_t i = 0; i < labels.size(); ++i) {
      (labels[i] == gf::kGround ? vg : vng).push_back(v[i]);
    }
    ref_g = widened(ref_g, vg);
    ref_ng = widened(ref_ng, vng);
    for (const auto& pair : {std::make_pair(&g, &ref_g), std::make_pair(&ng, &ref_ng)}) {
      const PointCloud2& a = *pair.first;
      const PointCloud2& b = *pair.second;
      EXPECT_EQ(a.point_step, 20u);
      EXPECT_EQ(a.point_step, b.point_step);
      EXPECT_EQ(a.row_step, b.row_step);
      EXPECT_EQ(a.width, b.width);
      EXPECT_EQ(a.is_dense, b.is_dense);
      ASSERT_EQ(a.fields.size(), 5u);
      EXPECT_EQ(a.fields.back().name, "height_above_ground");
      EXPECT_EQ(a.fields.back().offset, 16u);
      EXPECT_EQ(a.data, b.data);  // records, zeroed gaps and values byte for byte
    }
    EXPECT_EQ(g.width + ng.width, s.size());
    EXPECT_FALSE(ng.is_dense);  // it holds the NaN record
    // ~labeled: the label, then the height after it, in the same copy.
    PointCloud2 lab, ref_lab;
    lab.data.assign(2 * in.data.size(), 0xAB);
    std::string field_why;
    ASSERT_TRUE(gf::makeLabeledCloud(in, layout, labels, &lab, &why, &field, &field_why)) << why;
    EXPECT_TRUE(field_why.empty()) << field_why;
    ASSERT_TRUE(gf::makeLabeledCloud(in, layout, labels, &ref_lab, &why)) << why;
    ref_lab = widened(ref_lab, v);
    ASSERT_EQ(lab.fields.size(), 6u);
    EXPECT_EQ(lab.fields[4].name, "ground");
    EXPECT_EQ(lab.fields[4].offset, 14u);
    EXPECT_EQ(lab.fields[5].offset, 16u);
    EXPECT_EQ(lab.point_step, 20u);
    EXPECT_EQ(lab.height, 4u);
    EXPECT_EQ(lab.data, ref_lab.data);
    EXPECT_EQ(lab.row_step, ref_lab.row_step);
    // Filtered again (its own output as input): the field is overwritten in place.
    gf::CloudLayout again_layout;
    ASSERT_EQ(gf::checkPointCloud2(lab, &again_layout, nullptr), gf::CloudRejectReason::kNone);
    std::vector<float> w(v.size(), 7.f);
    gf::RecordFloatField again_field = field;
    again_field.values = &w;
    PointCloud2 g2, ng2;
    ASSERT_TRUE(gf::copySplit(lab, again_layout, labels, counts, &g2, &ng2, &again_field, &why));
    EXPECT_EQ(g2.point_step, 20u);
    EXPECT_EQ(g2.fields.size(), 6u);
    for (std::size_t k = 0; k < g2.width; ++k) ASSERT_EQ(floatAt(g2, k, 16), 7.f);
  }
  // A field of that name and another type: the records go out whole without it, the reason
  // named; ~labeled still goes out.
  PointCloud2 bad = s.cloud();
  bad.fields[3].name = gf::kHeightFieldName;
  gf::CloudLayout layout;
  ASSERT_EQ(gf::checkPointCloud2(bad, &layout, nullptr), gf::CloudRejectReason::kNone);
  std::vector<std::uint8_t> labels = s.labels;
  const gf::SplitCounts counts = gf::finalizeLabels(bad, layout, &labels);
  PointCloud2 g, ng, ref_g, ref_ng;
  std::string why;
  EXPECT_FALSE(gf::copySplit(bad, layout, labels, counts, &g, &ng, &field, &why));
  EXPECT_NE(why.find("height_above_ground"), std::string::npos);
  std::vector<std::uint8_t> ref_labels = s.labels;
  gf::splitPointCloud2(bad, layout, &ref_labels, &ref_g, &ref_ng);
  EXPECT_EQ(g.point_step, 14u);
  EXPECT_EQ(g.data, ref_g.data);
  EXPECT_EQ(ng.data, ref_ng.data);
  PointCloud2 lab, ref_lab;
  std::string field_why;
  ASSERT_TRUE(gf::makeLabeledCloud(bad, layout, labels, &lab, &why, &field, &field_why));
  EXPECT_NE(field_why.find("height_above_ground"), std::string::npos);
  ASSERT_TRUE(gf::makeLabeledCloud(bad, layout, labels, &ref_lab, &why));
  EXPECT_EQ(lab.data, ref_lab.data);
  EXPECT_EQ(lab.fields.size(), 5u);
  // ~obstacles the same way.
  const std::vector<float> h(s.size(), 1.f);  // every non-ground point in the band
  PointCloud2 obs, ref_obs;
  why.clear();
  EXPECT_FALSE(gf::makeObstacleCloud(bad, layout, labels, h, gf::ObstacleBand(), &obs,
                                     gf::kHeightFieldName, &why));
  EXPECT_NE(why.find("height_above_ground"), std::string::npos);
  EXPECT_TRUE(gf::makeObstacleCloud(bad, layout, labels, h, gf::ObstacleBand(), &ref_obs));
  EXPECT_EQ(obs.data, ref_obs.data);
  EXPECT_EQ(obs.point_step, 14u);
  EXPECT_EQ(obs.width, ng.width);  // every non-ground record: all heights are 1 m here
}

TEST(HagOutputs, BandValidation) {
  gf::ObstacleBand band;
  EXPECT_NO_THROW(band.validate());
  band.min_height = 2.5;
  EXPECT_THROW(band.validate(), std::invalid_argument);  // min == max
  band.min_height = std::nan("");
  EXPECT_THROW(band.validate(), std::invalid_argument);
}

// The nodelets' path (HagOutputs::process(), no ROS graph: no subscriber, ~labeled wanted) takes
// the scan type the filter reported: a car roof labelled ground amid its occlusion shadow (as in
// test_height_above_ground.cpp) is a spike for a ground-level scan only.
TEST(HagOutputs, ProcessSkipsTheShadowTestForAirborneScansOnly) {
  Scene s;
  for (float x = -10.f; x < 10.f; x += 0.25f) {
    for (float y = -10.f; y < 10.f; y += 0.25f) {
      const bool on_roof = x >= 2.f && x < 4.f && y >= 2.f && y < 4.f;
      const bool shadow = x >= 0.f && x < 6.f && y >= 0.f && y < 6.f;
      if (on_roof || !shadow) s.add(x, y, on_roof ? 1.4f : 0.f, gf::kGround);
    }
  }
  std::size_t roof = 0;  // the point at the roof's centre
  while (s.xyz[3 * roof] != 3.f || s.xyz[3 * roof + 1] != 3.f) ++roof;
  ASSERT_EQ(s.xyz[3 * roof + 2], 1.4f);
  const PointCloud2 in = s.cloud();
  gf::CloudLayout layout;
  ASSERT_EQ(gf::checkPointCloud2(in, &layout, nullptr), gf::CloudRejectReason::kNone);
  gf::CloudProcessingBuffers buffers;
  buffers.labels = s.labels;
  for (const char* type : {"ground", "registered", "airborne"}) {
    gf::ProcessedCloud filtered;
    filtered.stats.scan_type = type;
    gf::HagOutputs hag;
    gf::HagClouds clouds;
    const std::vector<float>* h =
        hag.process(in, layout, nullptr, buffers, "base_link", filtered, true, &clouds);
    ASSERT_NE(h, nullptr) << type;
    ASSERT_EQ(h->size(), s.size());
    const bool airborne = std::string(type) == "airborne";
    EXPECT_NEAR((*h)[roof], airborne ? 0.f : 1.4f, 1e-3f) << type;  // the roof kept / dropped
    EXPECT_NEAR((*h)[0], 0.f, 1e-3f) << type;
  }
}
