#ifndef GROUND_FILTER_SRC_CORE_NORMAL_CELL_KEYS_H
#define GROUND_FILTER_SRC_CORE_NORMAL_CELL_KEYS_H

// The grid keys of the normal filter's two sorts, from packed x y z: the grid-column (Morton)
// keys of the column order (OrderStage) and the tile keys of the plane stage (PlaneStage). The
// AVX2 path computes four points at a time with the same double arithmetic: the same keys on
// every path (test_simd_levels, CellKeys). Computed for every point of a scan, they took about a
// third of the sort stage on one core.

#include <cstddef>
#include <cstdint>

namespace ground_filter {
namespace normal {

/// \brief keys[i] = columnKey(cellIndex(x_i, min_x, inv_cell), cellIndex(y_i, min_y, inv_cell))
///        for i in [b, e) of packed `xyz`.
void columnKeysOf(const float* xyz, std::size_t b, std::size_t e, double min_x, double min_y,
                  double inv_cell, std::uint64_t* keys);

/// \brief keys[i] = cellIndex(x_i, min_x, inv_tile) << y_bits | cellIndex(y_i, min_y, inv_tile)
///        for i in [b, e) of packed `xyz` (PlaneStage's tile keys).
void tileKeysOf(const float* xyz, std::size_t b, std::size_t e, double min_x, double min_y,
                double inv_tile, int y_bits, std::uint64_t* keys);

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_CELL_KEYS_H
