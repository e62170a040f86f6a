// Unit tests of the nodelet plumbing without a ROS graph: PointCloud2 validation, the zero-copy
// view, the zero-loss split, and the agreement of cfg/VoxelGroundFilter.cfg with
// VoxelGroundFilterParams.
#include <dynamic_reconfigure/Config.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <boost/any.hpp>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "gf_test_clouds.h"
#include "ground_filter/working_volume.h"
#include "nodelet_monitor.h"
#include "param_check.h"
#include "point_cloud2.h"
#include "voxel_ground_filter_nodelet.h"

namespace gf = ground_filter;
using sensor_msgs::PointCloud2;
using sensor_msgs::PointField;

namespace {

using namespace gf_test;  // NOLINT(build/namespaces): the cloud builders (gf_test_clouds.h)

const std::uint8_t* record(const PointCloud2& c, std::size_t i) {
  return c.data.data() + (i / c.width) * c.row_step + (i % c.width) * c.point_step;
}

void setFloat(PointCloud2* c, std::size_t i, std::size_t offset, float v) {
  std::memcpy(const_cast<std::uint8_t*>(record(*c, i)) + offset, &v, sizeof(v));
}

gf::CloudRejectReason check(const PointCloud2& c, std::string* why = nullptr) {
  gf::CloudLayout layout;
  std::string message;
  const auto r = gf::checkPointCloud2(c, &layout, &message);
  if (why) *why = message;
  return r;
}

}  // namespace

// ------------------------------------------------------------------------------ validation

TEST(CheckPointCloud2, AcceptsAnyFieldOrderAndFindsOffsets) {
  const PointCloud2 c = makeCloud(10);
  gf::CloudLayout layout;
  std::string why;
  ASSERT_EQ(gf::checkPointCloud2(c, &layout, &why), gf::CloudRejectReason::kNone) << why;
  EXPECT_EQ(layout.x_offset, 8u);
  EXPECT_EQ(layout.y_offset, 12u);
  EXPECT_EQ(layout.z_offset, 4u);
  EXPECT_EQ(layout.points, 10u);
  EXPECT_TRUE(layout.contiguous);
}

TEST(CheckPointCloud2, EmptyCloudsAreValid) {
  EXPECT_EQ(check(makeCloud(0, 1)), gf::CloudRejectReason::kNone);
  EXPECT_EQ(check(makeCloud(0, 0)), gf::CloudRejectReason::kNone);
  EXPECT_EQ(check(makeCloud(5, 0)), gf::CloudRejectReason::kNone);
}

// Fuzzing found it: width 0 with a huge height walked billions of empty rows per pass.
TEST(CheckPointCloud2, ZeroWidthHugeHeightHasNoRowsToWalk) {
  PointCloud2 c = makeCloud(0, 1);
  c.height = 0xFFFFFFF0u;
  c.row_step = 0;
  c.data.clear();
  gf::CloudLayout layout;
  ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
  EXPECT_EQ(layout.points, 0u);
  EXPECT_EQ(layout.height, 0u);
  std::vector<std::uint8_t> labels;
  PointCloud2 g, ng, labeled;
  const gf::SplitCounts counts = gf::splitPointCloud2(c, layout, &labels, &g, &ng);
  EXPECT_EQ(counts.ground + counts.nonground, 0u);
  EXPECT_EQ(g.width + ng.width, 0u);
  std::string why;
  ASSERT_TRUE(gf::makeLabeledCloud(c, layout, labels, &labeled, &why));
  EXPECT_EQ(labeled.height, c.height);  // the header is kept
  EXPECT_TRUE(labeled.data.empty());
}

TEST(CheckPointCloud2, MissingField) {
  PointCloud2 c = makeCloud(4);
  c.fields.erase(c.fields.begin() + 1);  // z
  std::string why;
  EXPECT_EQ(check(c, &why), gf::CloudRejectReason::kMissingField);
  EXPECT_NE(why.find("no field 'z'"), std::string::npos) << why;
  EXPECT_EQ(check(PointCloud2()), gf::CloudRejectReason::kMissingField);
}

TEST(CheckPointCloud2, WrongTypeOrCount) {
  PointCloud2 c = makeCloud(4);
  c.fields[2].datatype = PointField::FLOAT64;  // x
  std::string why;
  EXPECT_EQ(check(c, &why), gf::CloudRejectReason::kFieldType);
  EXPECT_NE(why.find("field 'x'"), std::string::npos) << why;

  c = makeCloud(4);
  c.fields[3].count = 2;  // y
  EXPECT_EQ(check(c, &why), gf::CloudRejectReason::kFieldCount);
  c.fields[3].count = 0;
  EXPECT_EQ(check(c), gf::CloudRejectReason::kFieldCount);

  c = makeCloud(4);
  c.fields[4].datatype = 42;  // ring: unknown type
  EXPECT_EQ(check(c, &why), gf::CloudRejectReason::kFieldType);
  EXPECT_NE(why.find("ring"), std::string::npos) << why;
}

TEST(CheckPointCloud2, FieldPastPointStep) {
  PointCloud2 c = makeCloud(4);
  c.point_step = 16;  // ring @16 no longer fits; keep sizes consistent otherwise
  c.row_step = 4 * 16;
  c.data.resize(c.row_step);
  std::string why;
  EXPECT_EQ(check(c, &why), gf::CloudRejectReason::kFieldExtent);
  EXPECT_NE(why.find("ring"), std::string::npos) << why;

  c = makeCloud(4);
  c.fields.push_back(field("normal", 16, PointField::FLOAT32, 3));  // 16 + 12 > 24
  EXPECT_EQ(check(c), gf::CloudRejectReason::kFieldExtent);

  c = makeCloud(4);
  c.fields[2].offset = 22;  // x overlapping the end of the record
  EXPECT_EQ(check(c), gf::CloudRejectReason::kFieldExtent);
}

TEST(CheckPointCloud2, RowStepAndDataSize) {
  PointCloud2 c = makeCloud(4, 2);
  c.row_step -= 1;
  c.data.resize(std::size_t{c.row_step} * c.height);
  EXPECT_EQ(check(c), gf::CloudRejectReason::kRowStep);

  c = makeCloud(4, 2);
  c.data.pop_back();
  std::string why;
  EXPECT_EQ(check(c, &why), gf::CloudRejectReason::kDataSize);
  EXPECT_NE(why.find("data size"), std::string::npos) << why;

  c = makeCloud(4, 2);
  c.data.push_back(0);
  EXPECT_EQ(check(c), gf::CloudRejectReason::kDataSize);

  // width * point_step overflowing 32 bits must not wrap around.
  c = makeCloud(0, 1);
  c.width = 0x10000000u;
  c.row_step = 0;
  EXPECT_EQ(check(c), gf::CloudRejectReason::kRowStep);
}

TEST(CheckPointCloud2, BigEndianRejected) {
  PointCloud2 c = makeCloud(4);
  c.is_bigendian = true;
  EXPECT_EQ(check(c), gf::CloudRejectReason::kBigEndian);
}

// ------------------------------------------------------------------------------ view

TEST(MakeCloudView, ContiguousAndPaddedRows) {
  for (std::uint32_t pad : {0u, 8u}) {
    const PointCloud2 c = makeCloud(5, 3, pad);
    gf::CloudLayout layout;
    ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
    EXPECT_EQ(layout.contiguous, pad == 0);
    std::vector<float> scratch;
    const gf::CloudView v = gf::makeCloudView(c, layout, &scratch);
    ASSERT_EQ(v.size(), 15u);
    for (std::size_t i = 0; i < v.size(); ++i) {
      EXPECT_EQ(v.x(i), 1.0f * i);
      EXPECT_EQ(v.y(i), 2.0f * i);
      EXPECT_EQ(v.z(i), 3.0f * i);
    }
    EXPECT_EQ(scratch.empty(), pad == 0);  // zero-copy unless rows are padded
  }
}

TEST(SampledCentre, BoundingBoxMiddleOfFiniteRecordsAcrossPaddedRows) {
  for (std::uint32_t pad : {0u, 8u}) {
    PointCloud2 c = makeCloud(5, 3, pad);  // record i: x = i, y = 2 i, z = 3 i
    gf::CloudLayout layout;
    ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
    double m[3] = {-1.0, -1.0, -1.0};
    ASSERT_TRUE(gf::sampledCentre(c, layout, 4096, m));
    EXPECT_DOUBLE_EQ(m[0], 7.0);
    EXPECT_DOUBLE_EQ(m[1], 14.0);
    EXPECT_DOUBLE_EQ(m[2], 21.0);
    // The last record (row 2, column 4) non-finite: left out.
    const float nan = std::numeric_limits<float>::quiet_NaN();
    std::memcpy(&c.data[2 * c.row_step + 4 * c.point_step + 8], &nan, sizeof(nan));
    ASSERT_TRUE(gf::sampledCentre(c, layout, 4096, m));
    EXPECT_DOUBLE_EQ(m[0], 6.5);
    EXPECT_DOUBLE_EQ(m[2], 19.5);
    // At most max_samples records read: 8 of 15 at steps of 2 (0, 2, ..., 14, the last not
    // finite) reach record 12; reading every record would reach 13 (6.5).
    ASSERT_TRUE(gf::sampledCentre(c, layout, 8, m));
    EXPECT_DOUBLE_EQ(m[0], 6.0);
    EXPECT_DOUBLE_EQ(m[2], 18.0);
    // One sample: the first record only.
    ASSERT_TRUE(gf::sampledCentre(c, layout, 1, m));
    EXPECT_DOUBLE_EQ(m[0], 0.0);
    EXPECT_DOUBLE_EQ(m[1], 0.0);
  }
}

TEST(SampledCentre, EmptyOrAllNonFiniteGivesNone) {
  gf::CloudLayout layout;
  double m[3];
  const PointCloud2 empty = makeCloud(0, 1);
  ASSERT_EQ(gf::checkPointCloud2(empty, &layout, nullptr), gf::CloudRejectReason::kNone);
  EXPECT_FALSE(gf::sampledCentre(empty, layout, 4096, m));
  PointCloud2 c = makeCloud(4, 1);
  ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
  const float inf = std::numeric_limits<float>::infinity();
  for (std::uint32_t i = 0; i < 4; ++i) std::memcpy(&c.data[i * c.point_step + 4], &inf, 4);
  EXPECT_FALSE(gf::sampledCentre(c, layout, 4096, m));
}

// ------------------------------------------------------------------------------ split

TEST(SplitPointCloud2, EveryRecordOnceInOrderNaNToNonGround) {
  for (std::uint32_t pad : {0u, 8u}) {
    PointCloud2 c = makeCloud(6, 2, pad);
    setFloat(&c, 3, 8, std::numeric_limits<float>::quiet_NaN());  // x of point 3
    setFloat(&c, 7, 4, std::numeric_limits<float>::infinity());   // z of point 7
    c.is_dense = false;
    gf::CloudLayout layout;
    ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
    // A buggy filter calling the NaN/Inf points ground, and a label value of 2.
    std::vector<std::uint8_t> labels = {1, 0, 1, 1, 0, 0, 1, 1, 0, 1, 2, 0};
    PointCloud2 g, ng;
    const gf::SplitCounts n = gf::splitPointCloud2(c, layout, &labels, &g, &ng);
    EXPECT_EQ(n.invalid, 2u);
    const std::vector<std::size_t> want_g = {0, 2, 6, 9, 10}, want_ng = {1, 3, 4, 5, 7, 8, 11};
    EXPECT_EQ(n.ground, want_g.size());
    EXPECT_EQ(n.nonground, want_ng.size());
    for (const auto* out : {&g, &ng}) {
      EXPECT_EQ(out->header.frame_id, "velodyne");
      EXPECT_EQ(out->header.stamp.sec, 42u);
      EXPECT_EQ(out->fields.size(), c.fields.size());
      EXPECT_EQ(out->point_step, c.point_step);
      EXPECT_EQ(out->height, 1u);
      EXPECT_EQ(out->row_step, out->width * out->point_step);
      EXPECT_EQ(out->data.size(), out->row_step);
    }
    ASSERT_EQ(g.width, want_g.size());
    ASSERT_EQ(ng.width, want_ng.size());
    for (std::size_t k = 0; k < want_g.size(); ++k) {
      EXPECT_EQ(std::memcmp(g.data.data() + k * 24, record(c, want_g[k]), 24), 0) << k;
    }
    for (std::size_t k = 0; k < want_ng.size(); ++k) {
      EXPECT_EQ(std::memcmp(ng.data.data() + k * 24, record(c, want_ng[k]), 24), 0) << k;
    }
    EXPECT_TRUE(g.is_dense);
    EXPECT_FALSE(ng.is_dense);
    EXPECT_EQ(labels[3], gf::kNonGround);
    EXPECT_EQ(labels[10], gf::kGround);
  }
}

TEST(SplitPointCloud2, EmptyCloudGivesTwoEmptyClouds) {
  const PointCloud2 c = makeCloud(0);
  gf::CloudLayout layout;
  ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
  std::vector<std::uint8_t> labels;
  PointCloud2 g, ng;
  const gf::SplitCounts n = gf::splitPointCloud2(c, layout, &labels, &g, &ng);
  EXPECT_EQ(n.ground + n.nonground, 0u);
  EXPECT_EQ(g.width, 0u);
  EXPECT_EQ(ng.width, 0u);
  EXPECT_TRUE(g.data.empty());
  EXPECT_EQ(g.fields.size(), c.fields.size());
  EXPECT_TRUE(ng.is_dense);
}

// ------------------------------------------------------------------------------ cfg <-> Params

namespace {

std::string valueText(const gf::VoxelGroundFilterConfig::AbstractParamDescription& d,
                      const gf::VoxelGroundFilterConfig& config) {
  boost::any v;
  d.getValue(config, v);
  std::ostringstream os;
  os.precision(17);
  if (d.type == "double")
    os << boost::any_cast<double>(v);
  else if (d.type == "int")
    os << boost::any_cast<int>(v);
  else if (d.type == "bool")
    os << (boost::any_cast<bool>(v) ? "true" : "false");
  else
    os << boost::any_cast<std::string>(v);
  return os.str();
}

// `base` with only parameter `d` taken from `from`.
gf::VoxelGroundFilterConfig withOne(const gf::VoxelGroundFilterConfig::AbstractParamDescription& d,
                                    const gf::VoxelGroundFilterConfig& base,
                                    const gf::VoxelGroundFilterConfig& from) {
  dynamic_reconfigure::Config msg;
  d.toMessage(msg, from);
  gf::VoxelGroundFilterConfig out = base;
  d.fromMessage(msg, out);
  return out;
}

}  // namespace

// The names VoxelGroundFilterParams::set() knows (listed in its "unknown parameter" message).
std::vector<std::string> knownVoxelParamNames() {
  std::vector<std::string> names;
  try {
    gf::VoxelGroundFilterParams().set("no_such_parameter", "0");
  } catch (const std::invalid_argument& e) {
    const std::string text = e.what();
    const auto begin = text.find("known: ");
    const auto end = text.find(')', begin);
    if (begin == std::string::npos || end == std::string::npos) return names;
    std::istringstream list(text.substr(begin + 7, end - begin - 7));
    std::string name;
    while (std::getline(list, name, ',')) {
      name.erase(0, name.find_first_not_of(' '));
      names.push_back(name);
    }
  }
  return names;
}

// Every Params field (as named by set()) has a cfg parameter, and the other way round.
TEST(VoxelCfg, SameParameterNamesAsParams) {
  std::vector<std::string> cfg_names;
  for (const auto& d : gf::VoxelGroundFilterConfig::__getParamDescriptions__()) {
    // max_range and min_range belong to the working volume around every filter, the obstacle
    // band to the height-above-ground outputs (hag_outputs.h), not to its Params.
    if (d->name != "max_range" && d->name != "min_range" && d->name.rfind("obstacle_", 0) != 0) {
      cfg_names.push_back(d->name);
    }
  }
  std::vector<std::string> params_names = knownVoxelParamNames();
  ASSERT_FALSE(params_names.empty()) << "could not read the names from set()'s error message";
  std::sort(cfg_names.begin(), cfg_names.end());
  std::sort(params_names.begin(), params_names.end());
  EXPECT_EQ(cfg_names, params_names) << "cfg/VoxelGroundFilter.cfg is out of sync with "
                                        "VoxelGroundFilterParams";
}

TEST(VoxelCfg, DefaultsAreTheLibraryDefaults) {
  const auto params = gf::paramsFromConfigTable<gf::VoxelGroundFilterParams>(
      gf::VoxelGroundFilterConfig::__getDefault__());
  EXPECT_EQ(params.describe(), gf::VoxelGroundFilterParams().describe());
}

// Each cfg parameter is a Params field of the same name, mapped to it, and every value the cfg
// range allows for it (min, max; others at default) passes Params::validate().
TEST(VoxelCfg, EveryParameterMapsToItsFieldAndItsRangeValidates) {
  const auto& defaults = gf::VoxelGroundFilterConfig::__getDefault__();
  const auto& descriptions = gf::VoxelGroundFilterConfig::__getParamDescriptions__();
  ASSERT_FALSE(descriptions.empty());
  for (const auto& d : descriptions) {
    if (d->name == "max_range" || d->name == "min_range") continue;  // WorkingVolume, below
    if (d->name.rfind("obstacle_", 0) == 0) continue;  // ObstacleBand (test_hag_outputs)
    if (d->type == "str") continue;  // no range: an enum (scan_type's values: test_scan_type)
    for (const auto* bound :
         {&gf::VoxelGroundFilterConfig::__getMin__(), &gf::VoxelGroundFilterConfig::__getMax__()}) {
      const gf::VoxelGroundFilterConfig config = withOne(*d, defaults, *bound);
      const auto mapped = gf::paramsFromConfigTable<gf::VoxelGroundFilterParams>(config);
      gf::VoxelGroundFilterParams by_name;
      ASSERT_NO_THROW(by_name.set(d->name, valueText(*d, config)))
          << "cfg parameter '" << d->name << "' is not a VoxelGroundFilterParams field";
      EXPECT_EQ(mapped.describe(), by_name.describe())
          << "cfg parameter '" << d->name << "' not mapped onto its field";
      if (d->name == "tile_size" || d->name == "voxel_size" || d->name == "veg_min_height" ||
          d->name == "veg_max_height") {
        continue;  // cross-field rules below
      }
      EXPECT_NO_THROW(mapped.validate()) << d->name << " = " << valueText(*d, config);
    }
  }
  // tile_size >= 2 * voxel_size: the extremes that satisfy it validate.
  gf::VoxelGroundFilterConfig c = defaults;
  c.voxel_size = gf::VoxelGroundFilterConfig::__getMin__().voxel_size;
  c.tile_size = gf::VoxelGroundFilterConfig::__getMin__().tile_size;
  EXPECT_NO_THROW(gf::paramsFromConfigTable<gf::VoxelGroundFilterParams>(c).validate());
  c.voxel_size = gf::VoxelGroundFilterConfig::__getMax__().voxel_size;
  c.tile_size = gf::VoxelGroundFilterConfig::__getMax__().tile_size;
  EXPECT_NO_THROW(gf::paramsFromConfigTable<gf::VoxelGroundFilterParams>(c).validate());
  // veg_min_height <= veg_max_height: both ends of the band at either extreme validate, an
  // inverted band does not.
  for (const auto* bound :
       {&gf::VoxelGroundFilterConfig::__getMin__(), &gf::VoxelGroundFilterConfig::__getMax__()}) {
    c = defaults;
    c.veg_min_height = bound->veg_min_height;
    c.veg_max_height = bound->veg_max_height;
    EXPECT_NO_THROW(gf::paramsFromConfigTable<gf::VoxelGroundFilterParams>(c).validate());
  }
  c = defaults;
  c.veg_min_height = c.veg_max_height + 0.1;
  EXPECT_THROW(gf::paramsFromConfigTable<gf::VoxelGroundFilterParams>(c).validate(),
               std::invalid_argument);
}

// max_range: the cfg default is the library's and its whole range is a valid WorkingVolume.
TEST(VoxelCfg, MaxRangeIsTheWorkingVolume) {
  EXPECT_EQ(gf::VoxelGroundFilterConfig::__getDefault__().max_range, gf::kDefaultMaxRange);
  EXPECT_EQ(gf::VoxelGroundFilterConfig::__getMax__().max_range, gf::kWorkingVolumeHardLimit);
  for (double r : {gf::VoxelGroundFilterConfig::__getMin__().max_range,
                   gf::VoxelGroundFilterConfig::__getMax__().max_range}) {
    gf::WorkingVolume v;
    v.max_range = r;
    EXPECT_NO_THROW(v.validate()) << r;
  }
  // min_range: off by default; its range is valid with max_range off, and refused at or above
  // an active max_range.
  EXPECT_EQ(gf::VoxelGroundFilterConfig::__getDefault__().min_range, 0.0);
  gf::WorkingVolume v;
  v.max_range = 0.0;
  v.min_range = gf::VoxelGroundFilterConfig::__getMax__().min_range;
  EXPECT_NO_THROW(v.validate());
  v.max_range = 100.0;
  EXPECT_THROW(v.validate(), std::invalid_argument);
}

// Start-up check of the private parameters: unknown keys, wrong types and values outside the
// .cfg range are each named once; good values pass.
TEST(ParamCheck, NamesEveryBadKey) {
  std::vector<gf::ParamCheck> known = gf::baseParamChecks();
  gf::ParamCheck d;
  d.name = "plane_distance";
  d.ranged = true;
  d.min = 0.001;
  d.max = 10.0;
  known.push_back(d);
  gf::ParamCheck i;
  i.name = "threads";
  i.type = gf::ParamCheck::Type::kInt;
  i.ranged = true;
  i.min = 0;
  i.max = 256;
  known.push_back(i);
  std::map<std::string, XmlRpc::XmlRpcValue> set;
  set["plane_distance"] = XmlRpc::XmlRpcValue(0.2);
  set["threads"] = XmlRpc::XmlRpcValue(2);
  set["lazy"] = XmlRpc::XmlRpcValue(false);
  set["gravity_frame"] = XmlRpc::XmlRpcValue(std::string("base_link"));
  set["tf_timeout"] = XmlRpc::XmlRpcValue(1);  // an integer is a number
  XmlRpc::XmlRpcValue box;
  box.setSize(6);
  for (int k = 0; k < 6; ++k) box[k] = (k % 2) ? 1.0 : -1.0;
  box[5] = 2;  // integers in the list too
  set["body_box"] = box;
  std::vector<std::string> refused;
  EXPECT_TRUE(gf::checkPrivateParams(set, known, &refused).empty());
  EXPECT_TRUE(refused.empty());

  set["plane_distanse"] = XmlRpc::XmlRpcValue(0.2);              // unknown
  set["threads"] = XmlRpc::XmlRpcValue(std::string("two"));      // wrong type
  set["plane_distance"] = XmlRpc::XmlRpcValue(50.0);             // out of range
  set["lazy"] = XmlRpc::XmlRpcValue(std::string("no"));          // a string, not bool
  set["tf_timeout"] = XmlRpc::XmlRpcValue(std::string("fast"));  // wrong type
  box[2] = XmlRpc::XmlRpcValue(std::string("x"));
  set["body_box"] = box;  // not all numbers
  const std::vector<std::string> errors = gf::checkPrivateParams(set, known, &refused);
  const std::vector<std::string> keys = {"body_box",       "lazy",       "plane_distance",
                                         "plane_distanse", "tf_timeout", "threads"};
  EXPECT_EQ(refused, keys);
  ASSERT_EQ(errors.size(), keys.size());
  for (std::size_t k = 0; k < keys.size(); ++k) {
    EXPECT_EQ(errors[k].compare(0, keys[k].size() + 1, keys[k] + ":"), 0) << errors[k];
  }
  EXPECT_NE(errors[2].find("outside [0.001, 10]"), std::string::npos) << errors[2];
  EXPECT_NE(errors[3].find("unknown parameter (did you mean plane_distance?)"), std::string::npos)
      << errors[3];
  set.clear();
  set["colour"] = XmlRpc::XmlRpcValue(1);  // nothing close: one short line, no list of names
  const std::vector<std::string> far = gf::checkPrivateParams(set, known, nullptr);
  ASSERT_EQ(far.size(), 1u);
  EXPECT_EQ(far[0].rfind("colour: unknown parameter of this method", 0), 0u) << far[0];
  EXPECT_LT(far[0].size(), 160u) << far[0];
  EXPECT_EQ(far[0].find("queue_size"), std::string::npos) << far[0];
  EXPECT_NE(errors[5].find("'two' is not an integer"), std::string::npos) << errors[5];

  // The base parameters' numbers have ranges too (refused, not clamped in silence).
  set.clear();
  set["queue_size"] = XmlRpc::XmlRpcValue(0);
  set["tf_timeout"] = XmlRpc::XmlRpcValue(50.0);
  set["diagnostic_period"] = XmlRpc::XmlRpcValue(0.0);
  set["malloc_trim_period"] = XmlRpc::XmlRpcValue(-1.0);
  refused.clear();
  const std::vector<std::string> base = gf::checkPrivateParams(set, known, &refused);
  ASSERT_EQ(base.size(), 4u);
  EXPECT_NE(base[0].find("diagnostic_period: 0 is outside [0.01, 3600]"), std::string::npos)
      << base[0];
  EXPECT_NE(base[1].find("malloc_trim_period: -1 is outside [0, 3600]"), std::string::npos)
      << base[1];
  EXPECT_NE(base[2].find("queue_size: 0 is outside [1, 1000]"), std::string::npos) << base[2];
  EXPECT_NE(base[3].find("tf_timeout: 50 is outside [0, 10]"), std::string::npos) << base[3];
  set.clear();
  set["queue_size"] = XmlRpc::XmlRpcValue(1);
  set["tf_timeout"] = XmlRpc::XmlRpcValue(0);
  set["malloc_trim_period"] = XmlRpc::XmlRpcValue(0.0);  // 0 = off
  EXPECT_TRUE(gf::checkPrivateParams(set, known, nullptr).empty());
}

// ------------------------------------------------------------------------------ lost clouds

namespace {

// Feeds (seq, stamp) pairs in one frame; returns the lost count of each step.
std::vector<std::uint64_t> feed(gf::InputGapCounter* c,
                                const std::vector<std::pair<std::uint32_t, double>>& clouds,
                                const std::string& frame = "velodyne") {
  std::vector<std::uint64_t> lost;
  for (const auto& sc : clouds) lost.push_back(c->step(sc.first, sc.second, frame).lost);
  return lost;
}

using Lost = std::vector<std::uint64_t>;

}  // namespace

// seq keeps a counter (rospy, rosbag, make_bag.py): once it is confirmed (three small forward
// steps in a row, two of them +1), each gap is exact, whatever the stamps say.
TEST(InputGapCounter, SeqGapsAreExact) {
  gf::InputGapCounter c;
  EXPECT_EQ(feed(&c, {{10, 1.0}, {11, 1.1}, {12, 1.2}, {13, 1.3}}), Lost({0, 0, 0, 0}));
  EXPECT_EQ(feed(&c, {{15, 1.5}, {16, 1.6}, {20, 1.61}, {21, 1.62}}), Lost({1, 0, 3, 0}));
  const auto gap = c.step(23, 9.0, "velodyne");  // stamps jump, seq says one lost
  EXPECT_TRUE(gap.by_seq);
  EXPECT_EQ(gap.lost, 1u);
  EXPECT_EQ(gap.seq_from, 21u);
  EXPECT_EQ(gap.seq_to, 23u);
  // A bag's second scan lost while the filter built its first: counted once seq is confirmed,
  // named from the seq before it.
  gf::InputGapCounter b;
  EXPECT_EQ(feed(&b, {{0, 0.0}, {2, 0.2}, {3, 0.3}}), Lost({0, 0, 0}));
  const auto late = b.step(4, 0.4, "velodyne");
  EXPECT_EQ(late.lost, 1u);
  EXPECT_TRUE(late.by_seq);
  EXPECT_EQ(late.seq_from, 0u);
  EXPECT_EQ(late.seq_to, 4u);
  // seq steps of 2 every time are no counter of these clouds: nothing counted.
  gf::InputGapCounter two;
  EXPECT_EQ(feed(&two, {{0, 0.0}, {2, 0.1}, {4, 0.2}, {6, 0.3}, {8, 0.4}}), Lost(5, 0));
}

// uint32 wrap-around is a step of one; a publisher that restarts its counter (seq back to 0)
// counts nothing and seq counts again after three +1 steps.
TEST(InputGapCounter, SeqWrapAndRestart) {
  gf::InputGapCounter c;
  const std::uint32_t top = 0xFFFFFFFFu;
  EXPECT_EQ(feed(&c, {{top - 3, 0.0},
                      {top - 2, 0.1},
                      {top - 1, 0.2},
                      {top, 0.3},
                      {0, 0.4},
                      {1, 0.5},
                      {3, 0.6}}),
            Lost({0, 0, 0, 0, 0, 0, 1}));
  // Restart: seq 0 again (a restarted driver, a bag loop), stamps still every 0.1 s.
  EXPECT_EQ(feed(&c, {{4, 0.7}, {5, 0.8}, {0, 0.9}, {1, 1.0}}), Lost({0, 0, 0, 0}));
  // Not confirmed again yet (one +1 step): the gap 1 -> 5 waits, counted with the confirmation.
  EXPECT_EQ(feed(&c, {{5, 1.1}}), Lost({0}));
  EXPECT_EQ(feed(&c, {{6, 1.2}, {7, 1.3}, {8, 1.4}, {10, 1.5}}), Lost({3, 0, 0, 1}));
  // A jump beyond kMaxSeqStep is no gap (another publisher's counter); the stamps are regular.
  EXPECT_EQ(feed(&c, {{10 + 5000, 1.6}}), Lost({0}));
}

// seq left at 0 (many C++ drivers): the stamps against the median period.
TEST(InputGapCounter, StampGapsAgainstTheMedianPeriod) {
  gf::InputGapCounter c;
  // Five steps of ~0.1 s with jitter learn the period; nothing counted before.
  EXPECT_EQ(feed(&c, {{0, 10.0}, {0, 10.1}, {0, 10.21}, {0, 10.3}, {0, 10.39}, {0, 10.5}}),
            Lost({0, 0, 0, 0, 0, 0}));
  EXPECT_NEAR(c.period(), 0.1, 0.011);
  // 0.3 s: two lost; 0.14 s (jitter, below 1.5 periods): none; 0.2 s: one.
  EXPECT_EQ(feed(&c, {{0, 10.8}, {0, 10.94}, {0, 11.14}}), Lost({2, 0, 1}));
  const auto gap = c.step(0, 11.44, "velodyne");
  EXPECT_FALSE(gap.by_seq);
  EXPECT_EQ(gap.lost, 2u);
  EXPECT_NEAR(gap.step_s, 0.3, 1e-9);
  EXPECT_NEAR(gap.period_s, 0.1, 0.011);
}

// A bag played with --loop: the stamps jump back to the start. No negative or false count, and
// the clouds after the jump are judged as before; a hole longer than kMaxGapPeriods periods (a
// pause in the recording) is no loss either.
TEST(InputGapCounter, ClockJumpsBackAndHolesCountNothing) {
  gf::InputGapCounter c;
  std::vector<std::pair<std::uint32_t, double>> lap;
  for (int i = 0; i < 10; ++i) lap.push_back({0u, 100.0 + 0.1 * i});
  EXPECT_EQ(feed(&c, lap), Lost(10, 0));
  EXPECT_EQ(feed(&c, lap), Lost(10, 0));  // the jump back by 0.9 s and the second lap
  EXPECT_NEAR(c.period(), 0.1, 1e-6);     // the jump back did not enter the period
  EXPECT_EQ(feed(&c, {{0, 150.0}, {0, 150.1}}), Lost({0, 0}));  // a 49 s hole
  EXPECT_EQ(feed(&c, {{0, 150.1}, {0, 150.3}}), Lost({0, 1}));  // a repeated stamp, then a gap
  // The same with seq from a bag (make_bag.py writes seq = index): the loop restarts seq too.
  gf::InputGapCounter b;
  std::vector<std::pair<std::uint32_t, double>> bag;
  for (std::uint32_t i = 0; i < 10; ++i) bag.push_back({i, 100.0 + 0.1 * i});
  EXPECT_EQ(feed(&b, bag), Lost(10, 0));
  EXPECT_EQ(feed(&b, bag), Lost(10, 0));
  bag.erase(bag.begin() + 4);  // one lost in the third lap
  EXPECT_EQ(feed(&b, bag), Lost({0, 0, 0, 0, 1, 0, 0, 0, 0}));
}

// Two sensors on one topic (frame_id changes) and a restarted subscription: the cloud before is
// no reference.
TEST(InputGapCounter, FrameChangeAndRestartForgetThePreviousCloud) {
  gf::InputGapCounter c;
  EXPECT_EQ(feed(&c, {{0, 1.0}, {0, 1.1}, {0, 1.2}, {0, 1.3}, {0, 1.4}, {0, 1.5}}), Lost(6, 0));
  c.restart();
  EXPECT_EQ(feed(&c, {{0, 9.0}}), Lost({0}));  // 7.5 s later, after the restart: nothing lost
  EXPECT_GT(c.period(), 0.0);                  // the period is kept
  EXPECT_EQ(feed(&c, {{0, 9.3}}), Lost({2}));
  // Two sensors interleaved on one topic: every frame change forgets, nothing counted.
  for (int i = 0; i < 20; ++i) {
    EXPECT_EQ(c.step(0, 10.0 + 0.05 * i, i % 2 ? "front" : "rear").lost, 0u) << i;
  }
  EXPECT_EQ(c.period(), 0.0);
}

namespace {

// A filter that labels every point ground, or throws.
class StubFilter : public gf::GroundFilter {
 public:
  explicit StubFilter(bool fail) : fail_(fail) {}
  void filter(const gf::CloudView& cloud, std::vector<std::uint8_t>* labels,
              gf::FilterStats* stats) override {
    if (fail_) throw std::runtime_error("stub failure");
    labels->assign(cloud.size(), gf::kGround);
    if (stats) stats->ground_points = cloud.size();
  }
  std::string name() const override { return "stub"; }

 private:
  bool fail_;
};

}  // namespace

// The shared nodelet/fuzz path: far points go to non-ground through the working volume, NaN
// points too; a failing or missing filter publishes everything as non-ground; ~labeled matches.
TEST(ProcessPointCloud2, WorkingVolumeNaNAndFailures) {
  PointCloud2 c = makeCloud(40, 2, 8);  // organised, padded rows: x = i, y = 2i, z = 3i
  setFloat(&c, 5, 8, 1e30f);            // far
  setFloat(&c, 6, 12, 3e5f);            // far
  setFloat(&c, 7, 4, std::numeric_limits<float>::quiet_NaN());
  gf::CloudLayout layout;
  ASSERT_EQ(gf::checkPointCloud2(c, &layout, nullptr), gf::CloudRejectReason::kNone);
  gf::WorkingVolume volume;
  volume.max_range = 100.0;  // x = i, y = 2i, z = 3i: points 27..79 are farther than 100 m
  gf::WorkingVolumeFilter filter(std::make_unique<StubFilter>(false), volume);
  gf::CloudProcessingBuffers buffers;
  gf::ProcessedCloud out;
  gf::processPointCloud2(c, layout, &filter, nullptr, true, &buffers, &out);
  EXPECT_TRUE(out.filter_error.empty());
  std::size_t expect_far = 2;
  for (std::size_t i = 0; i < 80; ++i) {
    if (i != 5 && i != 6 && i != 7 && std::sqrt(14.0 * i * i) > 100.0) ++expect_far;
  }
  EXPECT_EQ(out.stats.out_of_range_points, expect_far);
  EXPECT_EQ(out.counts.invalid, 1u);
  EXPECT_EQ(out.counts.ground, 80u - expect_far - 1u);
  EXPECT_EQ(out.counts.ground + out.counts.nonground, 80u);
  ASSERT_TRUE(out.labeled);
  std::size_t labelled_ground = 0;
  for (std::size_t i = 0; i < 80; ++i) {
    labelled_ground += out.labeled->data[i * out.labeled->point_step + 24];
  }
  EXPECT_EQ(labelled_ground, out.counts.ground);

  gf::WorkingVolumeFilter failing(std::make_unique<StubFilter>(true), volume);
  gf::processPointCloud2(c, layout, &failing, nullptr, false, &buffers, &out);
  EXPECT_NE(out.filter_error.find("stub failure"), std::string::npos);
  EXPECT_EQ(out.counts.ground, 0u);
  EXPECT_EQ(out.counts.nonground, 80u);
  EXPECT_FALSE(out.labeled);
  gf::processPointCloud2(c, layout, nullptr, nullptr, false, &buffers, &out);
  EXPECT_FALSE(out.filter_error.empty());
  EXPECT_EQ(out.counts.nonground, 80u);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
