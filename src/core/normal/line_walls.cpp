// Step 7 of the normal filter (added): the lowest scan line of a wall or a car (line_walls.h).

#include "normal/line_walls.h"

#include <algorithm>
#include <cmath>

#include "ground_filter/ground_filter.h"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace normal {

namespace {
constexpr std::size_t kInsertionSort = 32;  // larger columns: std::stable_sort
}  // namespace

std::size_t LineWalls::run(const OrderedPoints& points, const std::uint64_t* columns,
                           const std::uint8_t* ground, const float sensor[3], double line_deg,
                           std::vector<std::uint8_t>* labels) {
  if (!(line_deg > 0.0)) return 0;
  const float gap = static_cast<float>(kGap);
  // Elevations a above b differ by at most the span where tan(a - b) <= tan(span).
  const double tan_span = std::tan(WallLines::kLineSpan * line_deg * M_PI / 180.0);
  const float* xyz = points.xyz.data();
  const std::uint32_t* source = points.source.data();
  const std::size_t n = points.source.size();
  std::uint8_t* lab = labels->data();
  if (!ground) {
    gathered_.resize(n);
    for (std::size_t k = 0; k < n; ++k) gathered_[k] = lab[source[k]];
    ground = gathered_.data();
  }
  if (!columns) {
    const ColumnGrid grid = columnGrid(points);
    keys_.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      keys_[k] = columnKey(cellIndex(xyz[3 * k], grid.min_x, grid.inv_cell),
                           cellIndex(xyz[3 * k + 1], grid.min_y, grid.inv_cell));
    }
    columns = keys_.data();
  }
  auto tanElevation = [&](std::uint32_t k) {
    const double dx = xyz[3 * k] - sensor[0], dy = xyz[3 * k + 1] - sensor[1];
    return (xyz[3 * k + 2] - sensor[2]) / std::max(std::sqrt(dx * dx + dy * dy), 1e-6);
  };
  // Layers [lb, le) and [le, ue) of column_: the upper one holds no ground, the lower one
  // does, and no line passed between them.
  auto oneSurface = [&](std::size_t lb, std::size_t le, std::size_t ue) {
    for (std::size_t j = le; j < ue; ++j) {
      if (ground[column_[j].k] == kGround) return false;
    }
    bool lower = false;
    for (std::size_t j = lb; j < le && !lower; ++j) lower = ground[column_[j].k] == kGround;
    if (!lower || column_[le].z - column_[le - 1].z > WallLines::kMaxRise) return false;
    const double a = tanElevation(column_[le].k), b = tanElevation(column_[le - 1].k);
    return a - b <= tan_span * (1.0 + a * b);
  };
  std::size_t relabelled = 0;
  // A column's points are consecutive: [b, e). Only one holding both labels can change.
  for (std::size_t b = 0; b < n;) {
    std::size_t e = b + 1;
    bool any_ground = ground[b] == kGround, any_other = !any_ground;
    for (; e < n && columns[e] == columns[b]; ++e) {
      const bool g = ground[e] == kGround;
      any_ground |= g;
      any_other |= !g;
    }
    if (any_ground && any_other) {
      column_.clear();
      for (std::size_t i = b; i < e; ++i) {
        column_.push_back({xyz[3 * i + 2], static_cast<std::uint32_t>(i)});
      }
      // By z, equal z in column order: a column of a sparse scan holds a few points, so
      // insertion sort, but any number (a pole beside the sensor) in n log n.
      auto byZ = [](const Layered& u, const Layered& v) { return u.z < v.z; };
      if (column_.size() <= kInsertionSort) {
        for (std::size_t i = 1; i < column_.size(); ++i) {
          const Layered p = column_[i];
          std::size_t j = i;
          for (; j > 0 && byZ(p, column_[j - 1]); --j) column_[j] = column_[j - 1];
          column_[j] = p;
        }
      } else {
        std::stable_sort(column_.begin(), column_.end(), byZ);
      }
      const std::size_t m = column_.size();
      std::size_t lb = 0, le = 1;
      while (le < m && column_[le].z - column_[le - 1].z < gap) ++le;
      while (le < m) {
        std::size_t ue = le + 1;
        while (ue < m && column_[ue].z - column_[ue - 1].z < gap) ++ue;
        if (oneSurface(lb, le, ue)) {
          for (std::size_t j = lb; j < le; ++j) {
            std::uint8_t& l = lab[source[column_[j].k]];
            relabelled += l == kGround;
            l = kNonGround;
          }
        }
        lb = le;
        le = ue;
      }
    }
    b = e;
  }
  return relabelled;
}

}  // namespace normal
}  // namespace ground_filter
