// Unit tests of the nodelet base's ROS extras without a ROS graph: the check of serialized
// PointCloud2 bytes (bad messages on the input), the `~labeled` cloud and the view of a cloud
// transformed into a gravity frame, and clouds with float64 x/y/z.
#include <gtest/gtest.h>
#include <ros/serialization.h>
#include <std_msgs/String.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <typeinfo>
#include <vector>

#include "cloud_subscription_helper.h"
#include "gf_test_clouds.h"
#include "ground_filter/ground_filter.h"
#include "nodelet_monitor.h"
#include "point_cloud2.h"

namespace gf = ground_filter;
using sensor_msgs::PointCloud2;
using sensor_msgs::PointField;

namespace {

using namespace gf_test;  // NOLINT(build/namespaces): the cloud builders (gf_test_clouds.h)

gf::CloudLayout layoutOf(const PointCloud2& c) {
  gf::CloudLayout layout;
  std::string why;
  EXPECT_EQ(gf::checkPointCloud2(c, &layout, &why), gf::CloudRejectReason::kNone) << why;
  return layout;
}

template <typename M>
std::vector<std::uint8_t> serialize(const M& msg) {
  std::vector<std::uint8_t> buf(ros::serialization::serializationLength(msg));
  ros::serialization::OStream stream(buf.data(), static_cast<std::uint32_t>(buf.size()));
  ros::serialization::serialize(stream, msg);
  return buf;
}

bool checkBytes(const std::vector<std::uint8_t>& b, std::string* why = nullptr) {
  std::string w;
  const bool ok =
      gf::checkSerializedPointCloud2(b.data(), static_cast<std::uint32_t>(b.size()), &w);
  if (why) *why = w;
  return ok;
}

const std::uint8_t* recordOf(const PointCloud2& c, std::size_t i) {
  return c.data.data() + (i / c.width) * c.row_step + (i % c.width) * c.point_step;
}

void putU32(std::vector<std::uint8_t>* b, std::size_t pos, std::uint32_t v) {
  std::memcpy(b->data() + pos, &v, 4);
}

}  // namespace

// The ~input subscription helper: PointCloud2 bytes become a message; bytes of another type
// (by md5sum or by content) are reported with their publisher and give no message.
TEST(CloudSubscriptionHelper, DeliversCloudsReportsOtherBytes) {
  std::vector<std::string> problems;
  gf::CloudSubscriptionHelper helper([](const sensor_msgs::PointCloud2ConstPtr&) {},
                                     [&problems](const std::string& what, const std::string& from) {
                                       problems.push_back(what + " | " + from);
                                     });
  EXPECT_TRUE(helper.getTypeInfo() == typeid(PointCloud2));
  std::vector<std::uint8_t> bytes = serialize(makeCloud(9, 2, 4));
  auto header = boost::make_shared<ros::M_string>();
  (*header)["md5sum"] = ros::message_traits::md5sum<PointCloud2>();
  (*header)["type"] = "sensor_msgs/PointCloud2";
  (*header)["callerid"] = "/player";
  ros::SubscriptionCallbackHelperDeserializeParams params;
  params.buffer = bytes.data();
  params.length = static_cast<std::uint32_t>(bytes.size());
  params.connection_header = header;
  const ros::VoidConstPtr msg = helper.deserialize(params);
  ASSERT_TRUE(msg);
  const auto cloud = boost::static_pointer_cast<const PointCloud2>(msg);
  EXPECT_EQ(cloud->width, 9u);
  EXPECT_EQ(cloud->height, 2u);
  EXPECT_TRUE(problems.empty());

  std::vector<std::uint8_t> text = serialize([] {
    std_msgs::String s;
    s.data = "hello";
    return s;
  }());
  params.buffer = text.data();
  params.length = static_cast<std::uint32_t>(text.size());
  EXPECT_FALSE(helper.deserialize(params));  // right md5sum, wrong bytes
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("do not decode"), std::string::npos) << problems[0];
  EXPECT_NE(problems[0].find("/player"), std::string::npos) << problems[0];

  (*header)["md5sum"] = ros::message_traits::md5sum<std_msgs::String>();
  (*header)["type"] = "std_msgs/String";
  params.buffer = bytes.data();
  params.length = static_cast<std::uint32_t>(bytes.size());
  EXPECT_FALSE(helper.deserialize(params));  // another type's connection, even cloud bytes
  ASSERT_EQ(problems.size(), 2u);
  EXPECT_NE(problems[1].find("std_msgs/String"), std::string::npos) << problems[1];
}

// With a pool, a delivered cloud that nobody holds any more lends its message (and its data
// buffer) to the next one, which comes out whole; one still held is never written over.
TEST(CloudSubscriptionHelper, PooledMessagesAreReusedOnlyWhenReleased) {
  gf::CloudPool pool(2);
  gf::CloudSubscriptionHelper helper([](const sensor_msgs::PointCloud2ConstPtr&) {},
                                     [](const std::string&, const std::string&) {}, &pool);
  auto header = boost::make_shared<ros::M_string>();
  (*header)["md5sum"] = ros::message_traits::md5sum<PointCloud2>();
  ros::SubscriptionCallbackHelperDeserializeParams params;
  params.connection_header = header;
  auto deliver = [&](const std::vector<std::uint8_t>& bytes) {
    params.buffer = const_cast<std::uint8_t*>(bytes.data());
    params.length = static_cast<std::uint32_t>(bytes.size());
    return boost::static_pointer_cast<const PointCloud2>(helper.deserialize(params));
  };
  const PointCloud2 big = makeCloud(50, 2, 8), small = makeCloud(7, 1, 0);
  const std::vector<std::uint8_t> big_bytes = serialize(big), small_bytes = serialize(small);
  auto first = deliver(big_bytes);
  ASSERT_TRUE(first);
  const PointCloud2* first_address = first.get();
  auto held = deliver(small_bytes);  // `first` is still held: another message
  ASSERT_TRUE(held);
  EXPECT_NE(held.get(), first_address);
  EXPECT_EQ(first->data, big.data);
  first.reset();
  auto again = deliver(small_bytes);  // the first message again, now holding the small cloud
  ASSERT_TRUE(again);
  EXPECT_EQ(again.get(), first_address);
  EXPECT_EQ(serialize(*again), small_bytes);
  EXPECT_EQ(serialize(*held), small_bytes);
  EXPECT_EQ(pool.reused(), 1u);
  EXPECT_EQ(pool.made(), 2u);
}

TEST(CheckSerializedPointCloud2, AcceptsRealMessages) {
  EXPECT_TRUE(checkBytes(serialize(makeCloud(100, 2, 8))));
  EXPECT_TRUE(checkBytes(serialize(PointCloud2())));  // empty cloud, no fields
}

TEST(CheckSerializedPointCloud2, RejectsOtherMessagesAndDamage) {
  const auto good = serialize(makeCloud(10));
  std::string why;
  // A std_msgs/String on the cloud topic (how a bag with mixed types replays).
  std_msgs::String s;
  s.data = "not a cloud";
  EXPECT_FALSE(checkBytes(serialize(s), &why));
  EXPECT_FALSE(why.empty());
  // One byte short, one byte too many, nothing at all.
  EXPECT_FALSE(checkBytes(std::vector<std::uint8_t>(good.begin(), good.end() - 1), &why));
  auto longer = good;
  longer.push_back(0);
  EXPECT_FALSE(checkBytes(longer, &why));
  EXPECT_NE(why.find("left over"), std::string::npos) << why;
  EXPECT_FALSE(checkBytes({}));
}

TEST(CheckSerializedPointCloud2, HugeLengthsAreRejectedBeforeAnyAllocation) {
  const PointCloud2 c = makeCloud(10);
  const auto good = serialize(c);
  // Layout: seq(4) stamp(8) frame_id(4 + n) height(4) width(4) field count(4) ...
  const std::size_t fields_pos = 12 + 4 + c.header.frame_id.size() + 8;
  auto bad = good;
  putU32(&bad, fields_pos, 0x7FFFFFFF);
  std::string why;
  EXPECT_FALSE(checkBytes(bad, &why));
  EXPECT_NE(why.find("field count"), std::string::npos) << why;
  // A data length beyond the buffer: it sits 4 + data bytes + 1 (is_dense) before the end.
  bad = good;
  putU32(&bad, good.size() - 1 - c.data.size() - 4, 0xFFFFFFF0u);
  EXPECT_FALSE(checkBytes(bad, &why));
  EXPECT_NE(why.find("data"), std::string::npos) << why;
  bad = good;
  putU32(&bad, 12, 0xFFFFFFFFu);  // frame_id length
  EXPECT_FALSE(checkBytes(bad, &why));
}

TEST(MakeLabeledCloud, AppendsAlignedUint8FieldAndDropsRowPadding) {
  const PointCloud2 in = makeCloud(5, 3, 12);
  const gf::CloudLayout layout = layoutOf(in);
  std::vector<std::uint8_t> labels(15);
  for (std::size_t i = 0; i < labels.size(); ++i) labels[i] = (i % 3 == 0) ? gf::kGround : 0;
  PointCloud2 out;
  std::string why;
  ASSERT_TRUE(gf::makeLabeledCloud(in, layout, labels, &out, &why)) << why;
  EXPECT_EQ(out.header.frame_id, in.header.frame_id);
  EXPECT_EQ(out.header.stamp, in.header.stamp);
  EXPECT_EQ(out.width, 5u);
  EXPECT_EQ(out.height, 3u);
  EXPECT_EQ(out.point_step, 28u);  // 24 + 1, rounded up to a multiple of 4
  EXPECT_EQ(out.row_step, 5u * 28u);
  ASSERT_EQ(out.data.size(), 15u * 28u);
  ASSERT_EQ(out.fields.size(), in.fields.size() + 1);
  const PointField& g = out.fields.back();
  EXPECT_EQ(g.name, "ground");
  EXPECT_EQ(g.offset, 24u);
  EXPECT_EQ(g.datatype, PointField::UINT8);
  EXPECT_EQ(g.count, 1u);
  for (std::size_t i = 0; i < 15; ++i) {
    const std::uint8_t* src = in.data.data() + (i / 5) * in.row_step + (i % 5) * 24;
    const std::uint8_t* dst = out.data.data() + i * 28;
    EXPECT_EQ(std::memcmp(src, dst, 24), 0) << "record " << i;
    EXPECT_EQ(dst[24], i % 3 == 0 ? 1 : 0) << "record " << i;
  }
}

TEST(MakeLabeledCloud, ReusesExistingUint8GroundFieldRefusesOtherTypes) {
  PointCloud2 in = makeCloud(4);
  in.fields.push_back(field("ground", 19, PointField::UINT8));  // a padding byte: free here
  const gf::CloudLayout layout = layoutOf(in);
  const std::vector<std::uint8_t> labels = {1, 0, 1, 0};
  PointCloud2 out;
  ASSERT_TRUE(gf::makeLabeledCloud(in, layout, labels, &out, nullptr));
  EXPECT_EQ(out.point_step, in.point_step);
  EXPECT_EQ(out.fields.size(), in.fields.size());
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(out.data[i * 24 + 19], labels[i]);

  in.fields.back().datatype = PointField::FLOAT32;
  in.fields.back().offset = 12;
  std::string why;
  EXPECT_FALSE(gf::makeLabeledCloud(in, layoutOf(in), labels, &out, &why));
  EXPECT_NE(why.find("ground"), std::string::npos) << why;
}

TEST(MakeTransformedCloudView, RotatesAndTranslatesKeepsNaN) {
  PointCloud2 in = makeCloud(3, 2, 4);  // padded rows: the transform reads row by row
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(in.data.data() + in.row_step + 24 + 12, &nan, 4);  // point 4: y = NaN
  const gf::CloudLayout layout = layoutOf(in);
  // 90 degrees about z, then +10 in z: (x, y, z) -> (-y, x, z + 10).
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(0, 0, 10);
  std::vector<float> scratch;
  const gf::CloudView v = gf::makeTransformedCloudView(in, layout, t, &scratch);
  ASSERT_EQ(v.size(), 6u);
  for (std::size_t i = 0; i < 6; ++i) {
    if (i == 4) {
      EXPECT_FALSE(v.isValid(i));
      continue;
    }
    EXPECT_NEAR(v.x(i), -2.0f * i, 1e-5) << i;  // -y = -2i
    EXPECT_NEAR(v.y(i), 1.0f * i, 1e-5) << i;   // x = i
    EXPECT_NEAR(v.z(i), 3.0f * i + 10.0f, 1e-5) << i;
  }
  // The cloud itself is untouched (outputs are copied from it).
  float x1;
  std::memcpy(&x1, in.data.data() + 24 + 8, 4);
  EXPECT_EQ(x1, 1.0f);
}

// Survey and map clouds with float64 x/y/z: accepted (all three, not mixed), filtered as
// float32, every record copied whole with its doubles; a NaN double counts as invalid.
TEST(MakeCloudView, Float64XyzIsPackedAndSplitWhole) {
  const double kBig = 1234.5678901234;  // more digits than a float holds
  for (std::uint32_t pad : {0u, 8u}) {
    PointCloud2 c =
        buildCloud({field("z", 0, PointField::FLOAT64), field("x", 8, PointField::FLOAT64),
                    field("y", 16, PointField::FLOAT64), field("ring", 24, PointField::UINT16)},
                   32, 4, 2, pad, 0xEE, 42, [&](std::uint8_t* rec, std::uint32_t i) {
                     const double v[3] = {3.0 * i, kBig + i, 2.0 * i};  // z, x, y
                     std::memcpy(rec, v, sizeof(v));
                     const std::uint16_t ring = static_cast<std::uint16_t>(i);
                     std::memcpy(rec + 24, &ring, 2);
                   });
    const double nan = std::numeric_limits<double>::quiet_NaN();
    std::memcpy(const_cast<std::uint8_t*>(recordOf(c, 5)) + 16, &nan, sizeof nan);  // y of 5
    gf::CloudLayout layout;
    ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
    EXPECT_TRUE(layout.float64);
    EXPECT_TRUE(layout.packed());
    std::vector<float> scratch;
    const gf::CloudView v = gf::makeCloudView(c, layout, &scratch);
    ASSERT_EQ(v.size(), 8u);
    EXPECT_EQ(scratch.size(), 24u);
    for (std::size_t i = 0; i < v.size(); ++i) {
      EXPECT_EQ(v.x(i), static_cast<float>(kBig + i));
      EXPECT_EQ(v.z(i), 3.0f * i);
    }
    double m[3];
    ASSERT_TRUE(gf::sampledCentre(c, layout, 4096, m));
    EXPECT_DOUBLE_EQ(m[0], kBig + 3.5);  // in double, not rounded to float
    std::vector<std::uint8_t> labels(8, gf::kGround);
    PointCloud2 g, ng;
    const gf::SplitCounts n = gf::splitPointCloud2(c, layout, &labels, &g, &ng);
    EXPECT_EQ(n.invalid, 1u);
    EXPECT_EQ(n.ground, 7u);
    ASSERT_EQ(ng.width, 1u);
    EXPECT_EQ(std::memcmp(ng.data.data(), recordOf(c, 5), 32), 0);
    for (std::size_t k = 0; k < 7; ++k) {
      EXPECT_EQ(std::memcmp(g.data.data() + k * 32, recordOf(c, k < 5 ? k : k + 1), 32), 0) << k;
    }
  }
  // x float64 with y and z float32: refused, naming both types.
  PointCloud2 mixed = makeCloud(4);
  mixed.fields[2].datatype = PointField::FLOAT64;  // x at 8..16 overlaps y: only the type counts
  std::string why;
  gf::CloudLayout layout;
  EXPECT_EQ(gf::checkPointCloud2(mixed, &layout, &why), gf::CloudRejectReason::kFieldType);
  EXPECT_NE(why.find("FLOAT32 (7) or all FLOAT64 (8)"), std::string::npos) << why;
}

// A map in projected coordinates published with float64 x/y/z (UTM 17N here): the view moves it
// onto its middle in double before narrowing, so float32 keep millimetres where they would step
// by 0.5 m at this northing, and the filter labels it with its sensor origin moved alike.
TEST(MakeCloudView, FarFloat64IsMovedInDoubleBeforeNarrowing) {
  const double e0 = 627000.123, n0 = 4842000.456, h0 = 101.5;  // where the tile lies
  std::vector<double> local;                                   // x y z per point, metres
  std::vector<bool> is_ground;
  for (int j = 0; j < 240; ++j) {  // 60 x 60 m of ground at 0.25 m, gently sloped, rough
    for (int i = 0; i < 240; ++i) {
      const double x = 0.25 * i + 0.003 * (j % 7), y = 0.25 * j + 0.002 * (i % 5);
      local.insert(local.end(), {x, y, 0.02 * x + 0.004 * ((i * 7 + j * 3) % 5)});
      is_ground.push_back(true);
    }
  }
  for (int b = 0; b < 6; ++b) {  // six boxes 2 x 4 m, 1.6 m high: their tops and sides
    const double bx = 6.0 + 9.0 * b, by = 10.0 + 7.0 * (b % 3);
    for (int j = 0; j <= 16; ++j) {
      for (int i = 0; i <= 8; ++i) {
        const double x = bx + 0.25 * i, y = by + 0.25 * j;
        local.insert(local.end(), {x, y, 0.02 * x + 1.6});
        is_ground.push_back(false);
        if (i == 0 || i == 8) {
          for (int k = 2; k < 6; ++k) {  // from 0.6 m: above the airborne threshold
            local.insert(local.end(), {x, y, 0.02 * x + 0.3 * k});
            is_ground.push_back(false);
          }
        }
      }
    }
  }
  const std::size_t n = is_ground.size();
  const PointCloud2 c = buildCloud(
      {field("x", 0, PointField::FLOAT64), field("y", 8, PointField::FLOAT64),
       field("z", 16, PointField::FLOAT64), field("intensity", 24, PointField::FLOAT32)},
      28, static_cast<std::uint32_t>(n), 1, 0, 0, 7, [&](std::uint8_t* rec, std::uint32_t i) {
        const double v[3] = {e0 + local[3 * i], n0 + local[3 * i + 1], h0 + local[3 * i + 2]};
        std::memcpy(rec, v, sizeof(v));
      });
  const gf::CloudLayout layout = layoutOf(c);
  std::vector<float> scratch;
  double shift[3];
  const gf::CloudView view = gf::makeCloudView(c, layout, &scratch, shift);
  ASSERT_EQ(view.size(), n);
  // The middle in whole metres (the tile spans about 60 m).
  EXPECT_NEAR(shift[0], e0 + 30.0, 2.0);
  EXPECT_NEAR(shift[1], n0 + 30.0, 2.0);
  EXPECT_NEAR(shift[2], h0 + 0.6, 2.0);
  for (int a = 0; a < 3; ++a) EXPECT_EQ(shift[a], std::round(shift[a]));
  double worst = 0.0, worst_unmoved = 0.0;
  std::vector<float> plain;
  const gf::CloudView unmoved = gf::makeCloudView(c, layout, &plain);  // no shift asked
  for (std::size_t i = 0; i < n; ++i) {
    worst = std::max(worst, std::fabs(view.y(i) - (n0 + local[3 * i + 1] - shift[1])));
    worst = std::max(worst, std::fabs(view.x(i) - (e0 + local[3 * i] - shift[0])));
    worst_unmoved = std::max(worst_unmoved, std::fabs(unmoved.y(i) - (n0 + local[3 * i + 1])));
  }
  EXPECT_LT(worst, 1e-4);         // float32 of values within 30 m
  EXPECT_GT(worst_unmoved, 0.1);  // float32 steps by 0.5 m at 4.8 million m
  // Through the nodelets' path: ground and boxes told apart; the note names the move; the
  // filter's sensor origin is back at the frame origin for the next cloud (same labels again).
  for (const char* method : {"voxel", "normal"}) {
    SCOPED_TRACE(method);
    std::unique_ptr<gf::GroundFilter> filter = gf::makeGroundFilter(method);
    gf::CloudProcessingBuffers buffers;
    gf::ProcessedCloud out;
    gf::processPointCloud2(c, layout, filter.get(), nullptr, false, &buffers, &out);
    ASSERT_TRUE(out.filter_error.empty()) << out.filter_error;
    for (int a = 0; a < 3; ++a) EXPECT_EQ(buffers.shift[a], shift[a]);
    EXPECT_NE(out.stats.scan_reason.find("moved by"), std::string::npos) << out.stats.scan_reason;
    EXPECT_EQ(out.stats.out_of_range_points, 0u) << out.stats.scan_reason;
    std::size_t ground_hit = 0, ground_all = 0, other_hit = 0, other_all = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const bool g = buffers.labels[i] == gf::kGround;
      (is_ground[i] ? ground_all : other_all) += 1;
      (is_ground[i] ? ground_hit : other_hit) += is_ground[i] ? g : !g;
    }
    EXPECT_GT(ground_hit, 0.99 * ground_all) << ground_hit << " of " << ground_all;
    EXPECT_GT(other_hit, 0.95 * other_all) << other_hit << " of " << other_all;
    const std::vector<std::uint8_t> first = buffers.labels;
    gf::processPointCloud2(c, layout, filter.get(), nullptr, false, &buffers, &out);
    EXPECT_EQ(buffers.labels, first);
  }
  // A gravity frame far from the sensor (a map frame in projected coordinates): moved likewise.
  const PointCloud2 sensor = makeCloud(50);  // float32, x = i, y = 2i, z = 3i
  Eigen::Isometry3d to_map = Eigen::Isometry3d::Identity();
  to_map.translation() = Eigen::Vector3d(e0, n0, h0);
  const gf::CloudView mapped =
      gf::makeTransformedCloudView(sensor, layoutOf(sensor), to_map, &scratch, shift);
  EXPECT_EQ(shift[1], std::round(n0 + 49.0));  // the middle of y = 0 .. 98
  for (std::size_t i = 0; i < mapped.size(); ++i) {
    EXPECT_NEAR(mapped.y(i), n0 + 2.0 * i - shift[1], 1e-4) << i;
  }
  // Garbage doubles (1e300 m) are no map: not moved (the offset must stay a float), every record
  // still goes out, as non-ground.
  const PointCloud2 garbage =
      buildCloud({field("x", 0, PointField::FLOAT64), field("y", 8, PointField::FLOAT64),
                  field("z", 16, PointField::FLOAT64)},
                 24, 200, 1, 0, 0, 7, [&](std::uint8_t* rec, std::uint32_t i) {
                   const double v[3] = {1e300 + i * 1e290, -1e300, 1e300};
                   std::memcpy(rec, v, sizeof(v));
                 });
  const gf::CloudLayout garbage_layout = layoutOf(garbage);
  gf::makeCloudView(garbage, garbage_layout, &scratch, shift);
  EXPECT_EQ(shift[0], 0.0);
  {
    std::unique_ptr<gf::GroundFilter> filter = gf::makeGroundFilter("voxel");
    gf::CloudProcessingBuffers buffers;
    gf::ProcessedCloud out;
    gf::processPointCloud2(garbage, garbage_layout, filter.get(), nullptr, false, &buffers, &out);
    EXPECT_EQ(out.counts.nonground, 200u);
  }
  // Near its origin a float64 cloud is packed as it is.
  const PointCloud2 near =
      buildCloud({field("x", 0, PointField::FLOAT64), field("y", 8, PointField::FLOAT64),
                  field("z", 16, PointField::FLOAT64)},
                 24, 100, 1, 0, 0, 7, [&](std::uint8_t* rec, std::uint32_t i) {
                   const double v[3] = {local[3 * i] + 4000.0, local[3 * i + 1], local[3 * i + 2]};
                   std::memcpy(rec, v, sizeof(v));
                 });
  gf::makeCloudView(near, layoutOf(near), &scratch, shift);
  EXPECT_EQ(shift[0], 0.0);
  EXPECT_EQ(shift[1], 0.0);
  EXPECT_EQ(scratch[0], static_cast<float>(local[0] + 4000.0));
}

// The nodelets log a filter note at once when its reason is new and once a minute when it
// repeats: a note that differs only in its numbers (a ramp's lean, scan after scan) repeats.
TEST(NoteKind, NumbersAsideTheSameReason) {
  using ground_filter::NodeletMonitor;
  std::string a, b, c;
  NodeletMonitor::noteKind(
      "the ground around the sensor leans 7.7 deg in the cloud's frame (level_tilt 5.0): the "
      "scan was turned onto it",
      &a);
  NodeletMonitor::noteKind(
      "the ground around the sensor leans 12.25 deg in the cloud's frame (level_tilt 5.0): the "
      "scan was turned onto it",
      &b);
  EXPECT_EQ(a, b);
  EXPECT_EQ(a,
            "the ground around the sensor leans # deg in the cloud's frame (level_tilt #): the "
            "scan was turned onto it");
  NodeletMonitor::noteKind("GPU search failed (out of memory); using kdtree", &c);
  EXPECT_NE(a, c);
  EXPECT_EQ(c, "GPU search failed (out of memory); using kdtree");  // no number: unchanged
  NodeletMonitor::noteKind("x/y/z on a 0.0625 / 0.5 / 0 m lattice. 240000 points.", &c);
  EXPECT_EQ(c, "x/y/z on a # / # / # m lattice. # points.");  // a sentence's point stays
  NodeletMonitor::noteKind("", &c);
  EXPECT_EQ(c, "");
  // Names with digits are numbers too: sm_87 and sm_72 are one reason.
  NodeletMonitor::noteKind("no kernel for sm_87", &a);
  NodeletMonitor::noteKind("no kernel for sm_72", &b);
  EXPECT_EQ(a, b);
}
