// The centre of a cloud's densest area and the ground's height there: where a spinning sensor
// sits when the cloud's origin is not it (a scan in a map frame). Used by the normal method's
// scan lines (common/scan_lines.cpp) and the voxel method's start segment.
#ifndef GROUND_FILTER_SRC_CORE_COMMON_DENSEST_CENTRE_H
#define GROUND_FILTER_SRC_CORE_COMMON_DENSEST_CENTRE_H

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief Finds the x/y centre of a cloud's densest area, keeping its buffers between calls.
class DensestCentre {
 public:
  /// \brief Points read, evenly spread over the cloud.
  static constexpr std::size_t kRead = 20000;
  /// \brief Cells of the first guess [m].
  static constexpr double kCell = 8.0;
  /// \brief Radius of each mean of the mean shift [m].
  static constexpr double kReach = 10.0;
  /// \brief Means taken.
  static constexpr int kShifts = 4;
  /// \brief Cell indices beyond this (2^21) in x or y join no cell: keys pack two of them.
  static constexpr double kMaxCellIndex = 2097152.0;

  /// \brief The mean of the points read in the densest kCell square, moved kShifts times to the
  ///        mean of those within kReach (a spinning sensor's points are densest around it), and
  ///        the 20th percentile of their z (the ground there), into c[0..2]; false for fewer than
  ///        1,000 finite points read (or none within kMaxCellIndex cells of the origin).
  bool find(const CloudView& cloud, float c[3]);

 private:
  std::vector<float> x_, y_, z_;
  std::vector<double> zs_;
  std::vector<std::pair<std::int64_t, std::uint32_t>> cells_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_DENSEST_CENTRE_H
