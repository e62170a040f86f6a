#ifndef GROUND_FILTER_SRC_CORE_COMMON_PLANE_FIT_H
#define GROUND_FILTER_SRC_CORE_COMMON_PLANE_FIT_H

#include <Eigen/Core>
#include <cstddef>

namespace ground_filter {

/// \brief Plane n . (p - origin) + d = 0 with a unit normal; the one plane type of the package.
///
/// PlaneAccumulator::fit() gives n.z >= 0 and origin 0; the normal filter's RANSAC keeps a point
/// of the cloud as origin (offsets stay small for far-away coordinates) and n's sign as fitted.
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit normal
  double d = 0.0;                                     ///< offset relative to `origin` [m]
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();   ///< reference point [m]

  /// \brief Signed distance of (x, y, z) [m], positive on the normal's side.
  double distance(double x, double y, double z) const {
    return normal.x() * (x - origin.x()) + normal.y() * (y - origin.y()) +
           normal.z() * (z - origin.z()) + d;
  }
};

/// \brief Accumulates first and second moments of points (double precision, centred on the
///        first point to keep far-away coordinates exact) and fits a least-squares plane.
class PlaneAccumulator {
 public:
  /// \brief Adds one point with weight w (inline: called per point in hot loops).
  void add(double x, double y, double z, double w = 1.0) {
    if (!has_ref_) {
      ref_ = Eigen::Vector3d(x, y, z);
      has_ref_ = true;
    }
    const double qx = x - ref_.x(), qy = y - ref_.y(), qz = z - ref_.z();
    w_ += w;
    s_.x() += w * qx;
    s_.y() += w * qy;
    s_.z() += w * qz;
    // Upper triangle only; fit() mirrors it.
    ss_(0, 0) += w * qx * qx;
    ss_(0, 1) += w * qx * qy;
    ss_(0, 2) += w * qx * qz;
    ss_(1, 1) += w * qy * qy;
    ss_(1, 2) += w * qy * qz;
    ss_(2, 2) += w * qz * qz;
  }
  /// \brief Adds all points of another accumulator.
  void merge(const PlaneAccumulator& other);
  /// \brief Sum of weights added.
  double weight() const { return w_; }
  /// \brief Fits the plane through the centroid along the smallest-eigenvalue direction.
  /// \param eigenvalues when not null, receives the covariance eigenvalues (ascending) [m^2].
  /// \return false with fewer than 3 points or when the points are (nearly) collinear.
  bool fit(Plane* plane, Eigen::Vector3d* eigenvalues = nullptr) const;

 private:
  bool has_ref_ = false;
  Eigen::Vector3d ref_ = Eigen::Vector3d::Zero();
  double w_ = 0.0;
  Eigen::Vector3d s_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d ss_ = Eigen::Matrix3d::Zero();  // second moments, upper triangle valid
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_PLANE_FIT_H
