#ifndef GROUND_FILTER_PLANE_FIT_H
#define GROUND_FILTER_PLANE_FIT_H

#include <Eigen/Core>
#include <cstddef>

namespace ground_filter {

/// \brief Plane n . p + d = 0 with a unit normal pointing up (n.z >= 0).
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit normal, n.z >= 0
  double d = 0.0;                                     ///< offset [m]

  /// \brief Signed distance of (x, y, z) [m], positive above the plane.
  double distance(double x, double y, double z) const {
    return normal.x() * x + normal.y() * y + normal.z() * z + d;
  }
};

/// \brief Accumulates first and second moments of points (double precision, centred on the
///        first point to keep far-away coordinates exact) and fits a least-squares plane.
class PlaneAccumulator {
 public:
  /// \brief Adds one point with weight w.
  void add(double x, double y, double z, double w = 1.0);
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
  Eigen::Matrix3d ss_ = Eigen::Matrix3d::Zero();
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_PLANE_FIT_H
