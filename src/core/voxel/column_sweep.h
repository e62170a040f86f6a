// Private to the voxel filter: the three-row sweep over the columns of a VoxelGrid.
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_COLUMN_SWEEP_H
#define GROUND_FILTER_SRC_CORE_VOXEL_COLUMN_SWEEP_H

#include <algorithm>
#include <array>
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

/// \brief Calls visit(q, r0, r1, r2) for every column q in [c0, c1) (whole rows, key order);
///        r0, r1 and r2 point at
///        entry y of the dense rows x - 1, x and x + 1 (y of column q), so r[0], r[1], r[2] are
///        the entries of columns y - 1, y, y + 1.
///
/// A row is `ny + 2` entries of T, all `empty` at first; fill(row, q) adds column q of that row
/// (entry y + 1 is column y; a fill may touch y .. y + 2), clear(row, q) undoes it. Three row
/// buffers (x mod 3) are reused, so a row is filled once however many columns read it.
template <typename T, typename Fill, typename Clear, typename Visit>
void sweepColumns(const VoxelGrid& g, std::size_t c0, std::size_t c1, std::vector<T>* buf,
                  const T& empty, Fill&& fill, Clear&& clear, Visit&& visit) {
  const std::size_t ncol = g.columns();
  const int y_bits = g.shift_x - g.shift_y;
  const std::uint64_t y_mask = g.mask_y;
  const std::uint64_t* ck = g.col_key.data();
  const std::size_t stride = g.ny + 2;
  buf->assign(3 * stride, empty);
  T* rows = buf->data();
  std::array<std::int64_t, 3> held_x = {-1, -1, -1};
  std::array<std::size_t, 3> held_b{}, held_e{};
  // Makes the buffer of row rx (rx mod 3) hold columns [b, e) of that row.
  auto put = [&](std::uint64_t rx, std::size_t b, std::size_t e) {
    const int k = static_cast<int>(rx % 3);
    if (held_x[k] == static_cast<std::int64_t>(rx)) return;
    T* row = rows + k * stride;
    for (std::size_t q = held_b[k]; q < held_e[k]; ++q) clear(row, q);
    for (std::size_t q = b; q < e; ++q) fill(row, q);
    held_x[k] = static_cast<std::int64_t>(rx);
    held_b[k] = b;
    held_e[k] = e;
  };
  std::size_t c = c0;
  if (c < c1 && (ck[c] >> y_bits) > 0) {  // the row before the range, if it has columns
    const std::uint64_t px = (ck[c] >> y_bits) - 1;
    std::size_t pb = c;
    while (pb > 0 && (ck[pb - 1] >> y_bits) == px) --pb;
    put(px, pb, c);
  }
  while (c < c1) {
    const std::uint64_t x = ck[c] >> y_bits;
    std::size_t ce = c;
    while (ce < ncol && (ck[ce] >> y_bits) == x) ++ce;
    std::size_t ne = ce;
    while (ne < ncol && (ck[ne] >> y_bits) == x + 1) ++ne;
    put(x, c, ce);
    put(x + 1, ce, ne);           // empty when row x + 1 has no columns
    if (x > 0) put(x - 1, 0, 0);  // no-op when row x - 1 is held (as x or x + 1), else cleared
    // At x == 0 the buffer of "x - 1" was never filled: all empty.
    const T* r0 = rows + ((x + 2) % 3) * stride;
    const T* r1 = rows + (x % 3) * stride;
    const T* r2 = rows + ((x + 1) % 3) * stride;
    for (std::size_t q = c; q < ce; ++q) {
      const std::uint64_t y = ck[q] & y_mask;
      visit(q, r0 + y, r1 + y, r2 + y);
    }
    c = ce;
  }
}

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_COLUMN_SWEEP_H
