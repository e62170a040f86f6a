// Private to the voxel filter: rows of columns of a VoxelGrid (ranges of whole rows, and the
// columns of the neighbouring rows found by walking them alongside, no dense row buffers).
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_COLUMN_SWEEP_H
#define GROUND_FILTER_SRC_CORE_VOXEL_COLUMN_SWEEP_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "voxel/voxel_grid.h"

namespace ground_filter {
namespace voxel {

/// \brief Splits the columns of `g` into `parts` ranges of whole rows (x): bounds[t] ..
///        bounds[t + 1] (size parts + 1; empty ranges where rows are few).
inline void splitRows(const VoxelGrid& g, int parts, std::vector<std::size_t>* bounds) {
  const std::size_t ncol = g.columns();
  const int y_bits = g.shift_x - g.shift_y;
  bounds->assign(static_cast<std::size_t>(parts) + 1, ncol);
  (*bounds)[0] = 0;
  for (int t = 1; t < parts; ++t) {
    std::size_t c = std::max(ncol * t / parts, (*bounds)[t - 1]);
    while (c > 0 && c < ncol && (g.col_key[c] >> y_bits) == (g.col_key[c - 1] >> y_bits)) ++c;
    (*bounds)[t] = c;
  }
}

/// \brief Calls visit(b, e, pb, pe, nb, ne) for every row of columns in [c0, c1) (whole rows,
///        key order): [b, e) are the columns of row x, [pb, pe) those of row x - 1 and [nb, ne)
///        those of row x + 1 (empty ranges where those rows have no columns).
template <typename Visit>
void forEachRow(const VoxelGrid& g, std::size_t c0, std::size_t c1, Visit&& visit) {
  const std::size_t ncol = g.columns();
  const int y_bits = g.shift_x - g.shift_y;
  const std::uint64_t* ck = g.col_key.data();
  auto rowOf = [&](std::size_t q) { return ck[q] >> y_bits; };
  std::size_t c = c0, known_e = c0;  // [c, known_e): this row, when the last step found it
  std::size_t pb = c0, pe = c0;      // previous row
  if (c0 < c1) {
    while (pb > 0 && rowOf(pb - 1) + 1 == rowOf(c0)) --pb;
  }
  while (c < c1) {
    const std::uint64_t x = rowOf(c);
    std::size_t e = known_e > c ? known_e : c;
    while (e < ncol && rowOf(e) == x) ++e;
    std::size_t ne = e;
    while (ne < ncol && rowOf(ne) == x + 1) ++ne;
    if (pe != c || pb == pe || rowOf(pb) + 1 != x) pb = pe = c;
    visit(c, e, pb, pe, e, ne);
    pb = c;
    pe = e;
    known_e = ne;
    c = e;
  }
}

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_COLUMN_SWEEP_H
