// Private to the normal filter: coordinates stored on a coarse lattice (float32 far from the
// origin, a coarse export), whose steps hide a neighbourhood's spread along an axis.
#ifndef GROUND_FILTER_SRC_CORE_NORMAL_LATTICE_H
#define GROUND_FILTER_SRC_CORE_NORMAL_LATTICE_H

#include <cstddef>
#include <vector>

#include "ground_filter/cloud_view.h"

namespace ground_filter {
namespace normal {

/// \brief Finds the lattice each coordinate axis of a cloud lies on, keeping its buffer from
///        call to call.
///
/// A float32 coordinate of 4.8 million m (a UTM northing) steps by 0.5 m: a dense cloud's K
/// nearest neighbours then often share one y, their covariance has no spread along y, and a
/// flat patch's smallest eigenvector lies along y instead of up (ground refused). Uniformly
/// placed inside a step, the hidden offsets have the variance step^2 / 12, which the PCA adds
/// back (CandidateTest::lattice_var).
class LatticeMeter {
 public:
  /// \brief Points sampled (evenly over the cloud, finite ones) per measurement.
  static constexpr std::size_t kSamples = 2048;
  /// \brief Least step taken for a lattice [m]: the spread a lidar's range noise gives anyway.
  static constexpr double kMinStep = 0.01;
  /// \brief Least positive gaps between the sorted sampled values to judge an axis.
  static constexpr std::size_t kMinGaps = 64;

  /// \brief The step of each axis into `step` [m], 0 where the axis is on no lattice: the
  ///        smallest positive gap between the sorted sampled values, when it is at least
  ///        kMinStep and every other gap is a whole multiple of it (within 5 %: natural
  ///        coordinates never are).
  /// \return whether any axis has a step.
  bool measure(const CloudView& cloud, double step[3]);

 private:
  // The step of one axis from an even sample of `samples` points; 0: none.
  double axisStep(const CloudView& cloud, int axis, std::size_t samples, std::size_t min_gaps);

  std::vector<float> values_;
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_LATTICE_H
