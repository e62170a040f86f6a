#ifndef GROUND_FILTER_WORKING_VOLUME_PARAMS_H
#define GROUND_FILTER_WORKING_VOLUME_PARAMS_H

#include <cmath>
#include <string>
#include <vector>

namespace ground_filter {

/// \brief Hard limit of the working volume [m]: a point farther than this from the origin along
///        any axis is always out of range, also with max_range 0 (off).
///
/// Chosen so no filter's index math can overflow: the whole volume spans at most 10 km per axis,
/// which the voxel grid holds (2^21 voxels per axis) down to the smallest voxel_size (0.005 m:
/// 10.49 km); the normal filter's grids adapt their cell size to any extent.
constexpr double kWorkingVolumeHardLimit = 5000.0;

/// \brief Default of the nodelets' `max_range` [m] (makeGroundFilter defaults to 0).
constexpr double kDefaultMaxRange = 1000.0;

/// \brief The volume in which points are filtered: a ball of `max_range` around `origin`,
///        clipped to the box of +- kWorkingVolumeHardLimit per axis around `origin`, less the
///        sensor's own surroundings: the ball of `min_range` around `origin` and the `body_box`
///        (the vehicle's own body returns).
struct WorkingVolume {
  double max_range = kDefaultMaxRange;  ///< ball radius, 0 = off (box only) [m] (1000)
  /// Points nearer than this to `origin` are excluded, 0 = off [m] (0).
  double min_range = 0.0;
  /// Excluded box [xmin, xmax, ymin, ymax, zmin, zmax] in the sensor (cloud) frame; empty =
  /// off, else 6 finite values with min <= max [m] (empty).
  std::vector<double> body_box;
  float origin[3] = {0.f, 0.f, 0.f};  ///< sensor origin in the view's frame [m] (0, 0, 0)
  /// Rotation from the sensor frame to the view's frame, row-major (identity): body_box is
  /// tested at R^T (p - origin).
  float rotation[9] = {1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f};

  /// \brief Checks max_range (0 or in (0, kWorkingVolumeHardLimit]), min_range (>= 0, below
  ///        max_range when that is on) and body_box (6 values, min <= max).
  /// \throws std::invalid_argument naming the key, the value and the range.
  void validate() const;
  /// \brief True when min_range or body_box is on: some points may be excluded().
  bool hasExclusions() const { return min_range > 0.0 || !body_box.empty(); }
  /// \brief True when the point (x, y, z) lies inside the volume (false for NaN/Inf); ignores
  ///        min_range and body_box (see excluded()).
  ///
  /// Float arithmetic, so the per-point check costs a few instructions; a distance that
  /// overflows (1e30 m) is Inf and so outside.
  bool contains(float x, float y, float z) const {
    const float dx = x - origin[0], dy = y - origin[1], dz = z - origin[2];
    const float h = static_cast<float>(kWorkingVolumeHardLimit);
    if (!(std::fabs(dx) <= h && std::fabs(dy) <= h && std::fabs(dz) <= h)) return false;
    const float r = static_cast<float>(max_range);
    return r == 0.f || dx * dx + dy * dy + dz * dz <= r * r;
  }
  /// \brief True when the finite point (x, y, z) is nearer than min_range to the origin or
  ///        inside body_box (bounds included).
  bool excluded(float x, float y, float z) const {
    const float dx = x - origin[0], dy = y - origin[1], dz = z - origin[2];
    const float r = static_cast<float>(min_range);
    if (dx * dx + dy * dy + dz * dz < r * r) return true;
    if (body_box.empty()) return false;
    const float* R = rotation;
    const float sx = R[0] * dx + R[3] * dy + R[6] * dz;
    const float sy = R[1] * dx + R[4] * dy + R[7] * dz;
    const float sz = R[2] * dx + R[5] * dy + R[8] * dz;
    return sx >= body_box[0] && sx <= body_box[1] && sy >= body_box[2] && sy <= body_box[3] &&
           sz >= body_box[4] && sz <= body_box[5];
  }
  /// \brief True when every point of the box [lo, hi] (finite bounds) lies inside: the test of
  ///        contains() rises with |x - origin| per axis, float rounding included, so the
  ///        corner farthest from the origin along every axis decides for all points.
  bool containsBox(const float lo[3], const float hi[3]) const {
    float corner[3];
    for (int d = 0; d < 3; ++d) {
      corner[d] = std::fabs(lo[d] - origin[d]) > std::fabs(hi[d] - origin[d]) ? lo[d] : hi[d];
    }
    return contains(corner[0], corner[1], corner[2]);
  }
};

/// \brief Parses a body box "[xmin, xmax, ymin, ymax, zmin, zmax]" (brackets optional, commas
///        or spaces), "" or "[]" = off.
/// \throws std::invalid_argument naming `key` when it is not 6 numbers.
std::vector<double> parseBodyBox(const std::string& key, const std::string& value);

}  // namespace ground_filter

#endif  // GROUND_FILTER_WORKING_VOLUME_PARAMS_H
