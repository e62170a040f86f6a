#ifndef GROUND_FILTER_CLOUD_VIEW_H
#define GROUND_FILTER_CLOUD_VIEW_H

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace ground_filter {

/// \brief Read-only, non-owning view of float32 x/y/z inside an array of point records.
///
/// Points are `stride` bytes apart; x, y and z are float32 at the given byte offsets inside a
/// record. A `sensor_msgs/PointCloud2` buffer or a packed `float[3*n]` can be viewed without
/// copying.
class CloudView {
 public:
  CloudView() = default;

  /// \brief View over `size` records of `stride` bytes with float x/y/z at the given byte offsets.
  CloudView(const void* data, std::size_t size, std::size_t stride, std::size_t x_offset = 0,
            std::size_t y_offset = 4, std::size_t z_offset = 8)
      : data_(static_cast<const std::uint8_t*>(data)),
        size_(size),
        stride_(stride),
        x_offset_(x_offset),
        y_offset_(y_offset),
        z_offset_(z_offset) {}

  /// \brief View over packed xyz triplets (`float[3 * size]`).
  static CloudView packedXyz(const float* xyz, std::size_t size) {
    return CloudView(xyz, size, 3 * sizeof(float), 0, sizeof(float), 2 * sizeof(float));
  }

  /// \brief Number of point records in the view.
  std::size_t size() const { return size_; }
  /// \brief True when the view holds no points.
  bool empty() const { return size_ == 0; }

  /// \brief x of point i (unaligned-safe read).
  float x(std::size_t i) const { return load(i, x_offset_); }
  /// \brief y of point i (unaligned-safe read).
  float y(std::size_t i) const { return load(i, y_offset_); }
  /// \brief z of point i (unaligned-safe read).
  float z(std::size_t i) const { return load(i, z_offset_); }

  /// \brief Reads x, y, z of point i; returns false when any of them is NaN or infinite.
  bool get(std::size_t i, float* px, float* py, float* pz) const {
    *px = x(i);
    *py = y(i);
    *pz = z(i);
    return std::isfinite(*px) && std::isfinite(*py) && std::isfinite(*pz);
  }

  /// \brief First byte of the records.
  const std::uint8_t* data() const { return data_; }
  /// \brief Bytes from one record to the next.
  std::size_t stride() const { return stride_; }
  /// \brief True when y and z follow x directly in every record (x y z: 12 adjacent bytes).
  bool xyzAdjacent() const {
    return y_offset_ == x_offset_ + 4 && z_offset_ == x_offset_ + 8 && x_offset_ + 12 <= stride_;
  }
  /// \brief True when y and z follow x directly and 4 more bytes of every record can be read
  ///        after z (x y z and one more float: one 16-byte load a point).
  bool xyzFollowedByFloat() const { return xyzAdjacent() && x_offset_ + 16 <= stride_; }
  /// \brief Byte offset of x in a record.
  std::size_t xOffset() const { return x_offset_; }
  /// \brief Byte offset of y in a record.
  std::size_t yOffset() const { return y_offset_; }
  /// \brief Byte offset of z in a record.
  std::size_t zOffset() const { return z_offset_; }

  /// \brief True when x, y and z of point i are all finite.
  bool isValid(std::size_t i) const {
    float px, py, pz;
    return get(i, &px, &py, &pz);
  }

 private:
  float load(std::size_t i, std::size_t offset) const {
    float v;
    std::memcpy(&v, data_ + i * stride_ + offset, sizeof(float));
    return v;
  }

  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
  std::size_t stride_ = 3 * sizeof(float);
  std::size_t x_offset_ = 0;
  std::size_t y_offset_ = 4;
  std::size_t z_offset_ = 8;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CLOUD_VIEW_H
