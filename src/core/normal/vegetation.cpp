// Optional stage after "plane" of the normal filter: the bush-base rule (veg_filter).

#include "vegetation.h"

#include <algorithm>
#include <cmath>

#include "cpu_gpu_common.h"

namespace ground_filter {
namespace normal {

namespace {

constexpr int kColumnBits = 21;  // per axis: 2^21 columns (210 km at 0.1 m)
constexpr std::uint64_t kColumnLimit = (1ULL << kColumnBits) - 1;
constexpr int kLevelBits = 64 - 2 * kColumnBits;

}  // namespace

std::size_t VegetationStage::run(const std::vector<float>& xyz, const std::vector<float>& height,
                                 const Extent& extent, const NormalGroundFilterParams& p,
                                 int threads, std::vector<std::uint8_t>* ground_out) {
  std::vector<std::uint8_t>& ground = *ground_out;
  const std::size_t n = height.size();
  const double inv = 1.0 / p.veg_cell;
  const int r = p.veg_radius;
  // Columns must fit the key (a cloud wider than 2^21 cells skips the rule).
  if (extent.size() * inv + 2.0 * r + 4.0 >= static_cast<double>(kColumnLimit)) return 0;
  // r + 1 columns of margin: every column index is >= r, so the window never goes below 0.
  const double margin = (r + 1) * p.veg_cell;
  const double lo_x = extent.min_x - margin, lo_y = extent.min_y - margin;

  // Clutter points and their voxels, sorted by column then level.
  clutter_.clear();
  float z_min = 0.0f;
  for (std::size_t i = 0; i < n; ++i) {
    const float h = height[i];
    if (h >= p.veg_min_height && h <= p.veg_max_height) {  // false for NaN
      const float z = xyz[3 * i + 2];
      z_min = clutter_.empty() ? z : std::min(z_min, z);
      clutter_.push_back(static_cast<std::uint32_t>(i));
    }
  }
  if (clutter_.size() < static_cast<std::size_t>(p.veg_min_points)) return 0;
  keys_.resize(clutter_.size());
  const std::uint64_t level_limit = (1ULL << kLevelBits) - 1;
  for (std::size_t c = 0; c < clutter_.size(); ++c) {
    const float* q = &xyz[3 * static_cast<std::size_t>(clutter_[c])];
    const std::uint64_t cx = cellIndex(q[0], lo_x, inv), cy = cellIndex(q[1], lo_y, inv);
    const std::uint64_t lz = std::min<std::uint64_t>(cellIndex(q[2], z_min, inv), level_limit);
    keys_[c] = (((cx << kColumnBits) | cy) << kLevelBits) | lz;
  }
  radixSortByKey(keys_, &order_, &scratch_);
  col_key_.clear();
  col_points_.clear();
  col_voxels_.clear();
  std::uint64_t prev = ~0ULL;
  for (const std::uint32_t o : order_) {
    const std::uint64_t key = keys_[o], col = key >> kLevelBits;
    if (col_key_.empty() || col_key_.back() != col) {
      col_key_.push_back(col);
      col_points_.push_back(0);
      col_voxels_.push_back(0);
    }
    ++col_points_.back();
    col_voxels_.back() += key != prev;
    prev = key;
  }

  // Every ground point high enough: the clutter of the window of columns around its own.
  // Consecutive points share columns (the cloud is in column order): the last sum is reused.
  std::size_t relabelled = 0;
  const int nt = static_cast<int>(std::min<std::size_t>(threads, n / 16384 + 1));
#pragma omp parallel num_threads(nt) reduction(+ : relabelled)
  {
    std::uint64_t last_col = ~0ULL;
    bool last_take = false;
#pragma omp for schedule(static)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
      if (!ground[i] || !(height[i] >= p.veg_min_base)) continue;
      const std::uint64_t cx = cellIndex(xyz[3 * i], lo_x, inv);
      const std::uint64_t cy = cellIndex(xyz[3 * i + 1], lo_y, inv);
      const std::uint64_t col = (cx << kColumnBits) | cy;
      if (col != last_col) {
        std::uint64_t points = 0, voxels = 0;
        for (std::uint64_t x = cx - r; x <= cx + r; ++x) {
          const std::uint64_t first = (x << kColumnBits) | (cy - r);
          const std::uint64_t last = (x << kColumnBits) | (cy + r);
          auto it = std::lower_bound(col_key_.begin(), col_key_.end(), first);
          for (; it != col_key_.end() && *it <= last; ++it) {
            const std::size_t c = static_cast<std::size_t>(it - col_key_.begin());
            points += col_points_[c];
            voxels += col_voxels_[c];
          }
        }
        last_col = col;
        last_take =
            points >= static_cast<std::uint64_t>(p.veg_min_points) &&
            (p.veg_max_density <= 0.0 ||
             static_cast<double>(points) <= p.veg_max_density * static_cast<double>(voxels));
      }
      if (last_take) {
        ground[i] = 0;
        ++relabelled;
      }
    }
  }
  return relabelled;
}

}  // namespace normal
}  // namespace ground_filter
