#ifndef GROUND_FILTER_POINT_FIELD_H
#define GROUND_FILTER_POINT_FIELD_H

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace ground_filter {

/// \brief A field of a point record that holds one value (count 1): `name` at byte `offset` of
///        the record, of type `datatype` (the PointField type constants, e.g. 7 = FLOAT32).
///        `Field` is a point-field type with the members name, offset, datatype and count:
///        sensor_msgs::PointField (the nodelets' clouds) or pcl::PCLPointField (the scan files);
///        the header depends on neither.
template <class Field>
Field singleValueField(const std::string& name, std::uint32_t offset, std::uint8_t datatype) {
  Field f;
  f.name = name;
  f.offset = offset;
  f.datatype = datatype;
  f.count = 1;
  return f;
}

/// \brief A float64 coordinate as the float32 the filters compute in; beyond the float range
///        +-Inf (a far point, then left out as non-finite), never an undefined conversion.
inline float narrowCoordinate(double v) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (v > kMax) return std::numeric_limits<float>::infinity();
  if (v < -kMax) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);
}

/// \brief The middle of one axis of a cloud in whole metres: halfway between the sampled values
///        `axis` (finite, not empty; reordered) without their outer percent on each side, so a
///        stray echo or a no-return placeholder does not move it. Where a cloud far from its
///        origin (projected coordinates) is moved to before it is filtered.
template <class T>
double trimmedMiddle(std::vector<T>* axis) {
  const std::size_t lo = axis->size() / 100, hi = axis->size() - 1 - lo;
  std::nth_element(axis->begin(), axis->begin() + lo, axis->end());
  const double a = (*axis)[lo];
  std::nth_element(axis->begin(), axis->begin() + hi, axis->end());
  return std::round(0.5 * (a + static_cast<double>((*axis)[hi])));
}

/// \brief Whether a cloud whose middle (trimmedMiddle() per axis) is `middle` is moved onto it
///        before its coordinates become float32: beyond `limit` on some axis (projected
///        coordinates), and within 1e30 on every axis (farther is no map but garbage, and the
///        offset must stay a float: the sensor origin moves by it).
inline bool moveOntoMiddle(const double middle[3], double limit) {
  bool far = false;
  for (int a = 0; a < 3; ++a) {
    if (!(std::fabs(middle[a]) <= 1e30)) return false;
    far = far || std::fabs(middle[a]) > limit;
  }
  return far;
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_POINT_FIELD_H
