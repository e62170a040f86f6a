// Test-only builders of sensor_msgs/PointCloud2 shared by the nodelet unit tests: the cloud frame
// (fields, steps, row padding) with records filled by a callback, and the tests' common cloud.
#ifndef GROUND_FILTER_TEST_GF_TEST_CLOUDS_H
#define GROUND_FILTER_TEST_GF_TEST_CLOUDS_H

#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/PointField.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace gf_test {

/// \brief One PointField.
inline sensor_msgs::PointField field(const std::string& name, std::uint32_t offset,
                                     std::uint8_t type, std::uint32_t count = 1) {
  sensor_msgs::PointField f;
  f.name = name;
  f.offset = offset;
  f.datatype = type;
  f.count = count;
  return f;
}

/// \brief A width x height cloud of `point_step`-byte records with `fields`, rows padded by
///        `row_pad` bytes, every byte `fill`; `record(r, c, i)` then writes point i (row r,
///        column c) through the returned pointer.
template <class WriteRecord>
sensor_msgs::PointCloud2 buildCloud(const std::vector<sensor_msgs::PointField>& fields,
                                    std::uint32_t point_step, std::uint32_t width,
                                    std::uint32_t height, std::uint32_t row_pad, std::uint8_t fill,
                                    std::uint32_t stamp_sec, WriteRecord write_record) {
  sensor_msgs::PointCloud2 c;
  c.header.frame_id = "velodyne";
  c.header.stamp.sec = stamp_sec;
  c.width = width;
  c.height = height;
  c.fields = fields;
  c.point_step = point_step;
  c.row_step = width * point_step + row_pad;
  c.data.assign(std::size_t{c.row_step} * height, fill);
  for (std::uint32_t r = 0, i = 0; r < height; ++r) {
    for (std::uint32_t col = 0; col < width; ++col, ++i) {
      write_record(c.data.data() + std::size_t{r} * c.row_step + col * point_step, i);
    }
  }
  c.is_dense = true;
  return c;
}

/// \brief The nodelet tests' cloud: 24-byte records with x/y/z not first, a uint16 field and
///        padding: intensity f32 @0, z @4, x @8, y @12, ring u16 @16, 6 bytes of padding @18.
///        Point i has x = i, y = 2i, z = 3i, intensity = 100 + i, ring = i, padding bytes = i;
///        rows padded by `row_pad` bytes of 0xEE.
inline sensor_msgs::PointCloud2 makeCloud(std::uint32_t width, std::uint32_t height = 1,
                                          std::uint32_t row_pad = 0) {
  using sensor_msgs::PointField;
  return buildCloud({field("intensity", 0, PointField::FLOAT32), field("z", 4, PointField::FLOAT32),
                     field("x", 8, PointField::FLOAT32), field("y", 12, PointField::FLOAT32),
                     field("ring", 16, PointField::UINT16)},
                    24, width, height, row_pad, 0xEE, 42, [](std::uint8_t* rec, std::uint32_t i) {
                      const float v[4] = {100.0f + i, 3.0f * i, 1.0f * i, 2.0f * i};
                      std::memcpy(rec, v, sizeof(v));
                      const std::uint16_t ring = static_cast<std::uint16_t>(i);
                      std::memcpy(rec + 16, &ring, 2);
                      std::memset(rec + 18, static_cast<int>(i & 0xFF), 6);
                    });
}

}  // namespace gf_test

#endif  // GROUND_FILTER_TEST_GF_TEST_CLOUDS_H
