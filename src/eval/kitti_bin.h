#ifndef GROUND_FILTER_SRC_EVAL_KITTI_BIN_H
#define GROUND_FILTER_SRC_EVAL_KITTI_BIN_H

// KITTI .bin scans read without PCL (the core-only builds have no scan_io): the tools and tests
// that need only the points of a scan.

#include <string>
#include <vector>

namespace ground_filter {

/// \brief The records of a KITTI .bin scan as they are in the file: float32 x y z intensity,
///        four floats a point (a CloudView with point_step 16 and x/y/z at 0/4/8 reads them).
/// \throws std::runtime_error when the file cannot be read or its size is not a multiple of 16 B.
std::vector<float> readKittiRecords(const std::string& path);

/// \brief x y z of every record of a KITTI .bin scan (non-finite ones too), three floats a point.
/// \throws std::runtime_error as readKittiRecords().
std::vector<float> readKittiXyz(const std::string& path);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_EVAL_KITTI_BIN_H
