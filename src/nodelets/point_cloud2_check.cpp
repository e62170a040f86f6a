#include <ros/serialization.h>
#include <sensor_msgs/PointField.h>

#include <cstring>
#include <exception>
#include <sstream>

#include "point_cloud2.h"

// Validation of PointCloud2 messages and of their serialized bytes (point_cloud2.h); the views,
// the split and the labelled cloud are in point_cloud2.cpp.

namespace ground_filter {

namespace {

std::size_t datatypeSize(std::uint8_t datatype) {
  switch (datatype) {
    case sensor_msgs::PointField::INT8:
    case sensor_msgs::PointField::UINT8:
      return 1;
    case sensor_msgs::PointField::INT16:
    case sensor_msgs::PointField::UINT16:
      return 2;
    case sensor_msgs::PointField::INT32:
    case sensor_msgs::PointField::UINT32:
    case sensor_msgs::PointField::FLOAT32:
      return 4;
    case sensor_msgs::PointField::FLOAT64:
      return 8;
    default:
      return 0;
  }
}

}  // namespace

const char* reasonName(CloudRejectReason r) {
  // In the order of CloudRejectReason.
  static const char* const kNames[] = {"none",        "big-endian",   "missing field", "field type",
                                       "field count", "field extent", "row_step",      "data size"};
  static_assert(sizeof(kNames) / sizeof(kNames[0]) == static_cast<int>(CloudRejectReason::kCount),
                "one name per CloudRejectReason");
  const int i = static_cast<int>(r);
  return i > 0 && i < static_cast<int>(CloudRejectReason::kCount) ? kNames[i] : "none";
}

CloudRejectReason checkPointCloud2(const sensor_msgs::PointCloud2& cloud, CloudLayout* layout,
                                   std::string* message) {
  std::ostringstream why;
  auto reject = [&](CloudRejectReason r) {
    if (message) *message = why.str();
    return r;
  };
  if (cloud.is_bigendian) {
    why << "is_bigendian is true; only little-endian data is supported";
    return reject(CloudRejectReason::kBigEndian);
  }
  // x, y and z: float32, one element each, anywhere inside the record.
  const char* axes[3] = {"x", "y", "z"};
  std::size_t offsets[3] = {0, 0, 0};
  std::uint8_t types[3] = {0, 0, 0};
  for (int a = 0; a < 3; ++a) {
    const sensor_msgs::PointField* found = nullptr;
    for (const auto& f : cloud.fields) {
      if (f.name == axes[a]) {
        found = &f;
        break;
      }
    }
    if (!found) {
      why << "no field '" << axes[a] << "' (fields:";
      for (const auto& f : cloud.fields) why << " " << f.name;
      why << ")";
      return reject(CloudRejectReason::kMissingField);
    }
    // float32, or float64 for all three (survey and map clouds; read as double, filtered as
    // float32 like any other cloud, the records copied unchanged).
    const std::uint8_t t = found->datatype, t0 = a == 0 ? t : types[0];
    if ((t != sensor_msgs::PointField::FLOAT32 && t != sensor_msgs::PointField::FLOAT64) ||
        t != t0) {
      why << "field 'x' has datatype " << static_cast<int>(t0);
      if (a > 0) why << " but '" << axes[a] << "' " << static_cast<int>(t);
      why << ": x, y and z must all be FLOAT32 ("
          << static_cast<int>(sensor_msgs::PointField::FLOAT32) << ") or all FLOAT64 ("
          << static_cast<int>(sensor_msgs::PointField::FLOAT64) << ")";
      return reject(CloudRejectReason::kFieldType);
    }
    types[a] = t;
    if (found->count != 1) {
      why << "field '" << axes[a] << "' has count " << found->count << ", expected 1";
      return reject(CloudRejectReason::kFieldCount);
    }
    offsets[a] = found->offset;
  }
  // Every field (x/y/z and the ones only copied) must lie inside the record.
  for (const auto& f : cloud.fields) {
    const std::size_t size = datatypeSize(f.datatype);
    if (size == 0) {
      why << "field '" << f.name << "' has unknown datatype " << static_cast<int>(f.datatype);
      return reject(CloudRejectReason::kFieldType);
    }
    const std::uint64_t end = std::uint64_t{f.offset} + std::uint64_t{size} * f.count;
    if (end > cloud.point_step) {
      why << "point_step " << cloud.point_step << " is smaller than field '" << f.name
          << "' (offset " << f.offset << " + " << f.count << " x " << size << " bytes = " << end
          << ")";
      return reject(CloudRejectReason::kFieldExtent);
    }
  }
  const std::uint64_t min_row = std::uint64_t{cloud.width} * cloud.point_step;
  if (cloud.row_step < min_row) {
    why << "row_step " << cloud.row_step << " < width " << cloud.width << " * point_step "
        << cloud.point_step << " (" << min_row << ")";
    return reject(CloudRejectReason::kRowStep);
  }
  const std::uint64_t expected = std::uint64_t{cloud.row_step} * cloud.height;
  if (cloud.data.size() != expected) {
    why << "data size " << cloud.data.size() << " != row_step " << cloud.row_step << " * height "
        << cloud.height << " (" << expected << ")";
    return reject(CloudRejectReason::kDataSize);
  }
  if (layout) {
    layout->x_offset = offsets[0];
    layout->y_offset = offsets[1];
    layout->z_offset = offsets[2];
    layout->float64 = types[0] == sensor_msgs::PointField::FLOAT64;
    layout->width = cloud.width;
    // No rows to walk when there is no point: a cloud of width 0 and height 4e9 must not cost
    // 4e9 empty row iterations in every pass (found by fuzzing: seconds per message).
    layout->height = cloud.width == 0 ? 0 : cloud.height;
    layout->point_step = cloud.point_step;
    layout->row_step = cloud.row_step;
    layout->points = std::size_t{cloud.width} * cloud.height;
    layout->contiguous = cloud.height <= 1 || cloud.row_step == min_row;
  }
  if (message) message->clear();
  return CloudRejectReason::kNone;
}

bool checkSerializedPointCloud2(const std::uint8_t* buf, std::uint32_t len, std::string* why) {
  std::size_t pos = 0;
  auto fail = [&](const char* what) {
    *why = std::string(what) + " at byte " + std::to_string(pos) + " of " + std::to_string(len);
    return false;
  };
  auto skip = [&](std::size_t n) {
    if (n > len - pos) return false;
    pos += n;
    return true;
  };
  auto u32 = [&](std::uint32_t* v) {
    if (len - pos < 4) return false;
    std::memcpy(v, buf + pos, 4);
    pos += 4;
    return true;
  };
  std::uint32_t n = 0;
  if (!skip(12)) return fail("header seq/stamp truncated");  // seq, stamp.sec, stamp.nsec
  if (!u32(&n) || !skip(n)) return fail("header frame_id truncated");
  if (!skip(8)) return fail("height/width truncated");
  std::uint32_t fields = 0;
  if (!u32(&fields)) return fail("field count truncated");
  if (fields > (len - pos) / 13) return fail("field count too large");  // >= 13 bytes each
  for (std::uint32_t i = 0; i < fields; ++i) {
    if (!u32(&n) || !skip(n)) return fail("field name truncated");
    if (!skip(9)) return fail("field offset/datatype/count truncated");
  }
  if (!skip(9)) return fail("is_bigendian/point_step/row_step truncated");
  if (!u32(&n) || !skip(n)) return fail("data truncated");
  if (!skip(1)) return fail("is_dense missing");
  if (pos != len) return fail("bytes left over");
  return true;
}

bool deserializePointCloud2(const std::uint8_t* buf, std::uint32_t len,
                            sensor_msgs::PointCloud2* msg, std::string* why) {
  if (!checkSerializedPointCloud2(buf, len, why)) return false;
  try {
    ros::serialization::IStream stream(const_cast<std::uint8_t*>(buf), len);
    ros::serialization::deserialize(stream, *msg);
  } catch (const std::exception& e) {
    *why = e.what();
    return false;
  }
  return true;
}

}  // namespace ground_filter
