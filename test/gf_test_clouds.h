// Test-only builders of sensor_msgs/PointCloud2 shared by the nodelet unit tests: the empty
// cloud frame (fields, steps, row padding) is built here; each test fills its own records.
#ifndef GROUND_FILTER_TEST_GF_TEST_CLOUDS_H
#define GROUND_FILTER_TEST_GF_TEST_CLOUDS_H

#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/PointField.h>

#include <cstddef>
#include <cstdint>
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

}  // namespace gf_test

#endif  // GROUND_FILTER_TEST_GF_TEST_CLOUDS_H
