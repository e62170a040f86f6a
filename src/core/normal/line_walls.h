// Private to the normal filter: the lowest scan line of a wall or a car seen by a sparse spinning
// sensor (step 7), per point, after the labels of either path (CPU stages or GPU).
#ifndef GROUND_FILTER_SRC_CORE_NORMAL_LINE_WALLS_H
#define GROUND_FILTER_SRC_CORE_NORMAL_LINE_WALLS_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/scan_lines.h"
#include "normal/order.h"

namespace ground_filter {
namespace normal {

/// \brief Step 7 (added): the voxel filter's step 10 in per-point form. A sparse spinning
///        sensor's lowest scan line on a wall or a car's side lies up to one line spacing above
///        the ground and passes the plane test; the next line up hits the same surface straight
///        above it. In each column of the ordering grid (cell_size, 0.1 m) the points in z
///        order fall into layers (kGap or more apart); a layer's ground points become non-ground
///        where the next layer up lies at most WallLines::kMaxRise higher, holds no ground point,
///        and is seen from the sensor less than WallLines::kLineSpan lines higher: no line
///        passed between them, so both lie on one upright surface. Ground under an overhang (a
///        bush, a tree, a car's sill) mostly has lines passing over it first and stays. Unlike
///        step 10 there is no lift test (the GPU returns labels, not plane heights): on KITTI
///        thinned to every 4th or 2nd ring, the real sparse scans, none is needed.
class LineWalls {
 public:
  /// \brief Least z gap between two layers of a column [m]: a surface seen densely has none
  ///        (flat from 0.02 to 0.07 m; at 0.1 m the generated 16- and 32-beam streets lose
  ///        0.1-0.3, where a wall 3 m away holds its lines 0.1 m apart).
  static constexpr double kGap = 0.05;

  /// \brief Rewrites `labels` (per input point, kGround / kNonGround; `points.source` maps the
  ///        ordered points to them), seen from `sensor` (x, y, z in the points' frame) whose
  ///        scan lines lie `line_deg` apart (0: nothing done). `columns`: each ordered point's
  ///        column key (OrderStage::columnKeys()), or null (computed here from the points' grid,
  ///        columnGrid()); `ground`: the labels per ordered point (read only), or null
  ///        (gathered here). Returns the points relabelled.
  std::size_t run(const OrderedPoints& points, const std::uint64_t* columns,
                  const std::uint8_t* ground, const float sensor[3], double line_deg,
                  std::vector<std::uint8_t>* labels);

 private:
  struct Layered {
    float z;
    std::uint32_t k;  // ordered point
  };
  std::vector<Layered> column_;         // one column's points in z order
  std::vector<std::uint8_t> gathered_;  // the labels per ordered point, where not given
  std::vector<std::uint64_t> keys_;     // the column keys, where not given
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_LINE_WALLS_H
