#include "common/plane_fit.h"

#include <Eigen/Eigenvalues>

namespace ground_filter {

void PlaneAccumulator::merge(const PlaneAccumulator& other) {
  if (other.w_ <= 0.0) return;
  if (!has_ref_) {
    *this = other;
    return;
  }
  // Re-centre the other's moments on our reference point.
  const Eigen::Vector3d delta = other.ref_ - ref_;
  w_ += other.w_;
  s_ += other.s_ + other.w_ * delta;
  ss_ += other.ss_ + other.s_ * delta.transpose() + delta * other.s_.transpose() +
         other.w_ * delta * delta.transpose();
}

bool PlaneAccumulator::fit(Plane* plane, Eigen::Vector3d* eigenvalues) const {
  if (w_ < 3.0) return false;
  const Eigen::Vector3d mean = s_ / w_;
  Eigen::Matrix3d ss = ss_;
  ss(1, 0) = ss(0, 1);
  ss(2, 0) = ss(0, 2);
  ss(2, 1) = ss(1, 2);
  const Eigen::Matrix3d cov = ss / w_ - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  const Eigen::Vector3d ev = es.eigenvalues();  // ascending
  // Collinear or single-point sets have two vanishing eigenvalues: no unique plane.
  if (!(ev(1) > 1e-12 + 1e-9 * ev(2))) return false;
  Eigen::Vector3d n = es.eigenvectors().col(0).normalized();
  if (n.z() < 0) n = -n;
  plane->normal = n;
  plane->d = -n.dot(mean + ref_);
  if (eigenvalues) *eigenvalues = ev;
  return true;
}

}  // namespace ground_filter
