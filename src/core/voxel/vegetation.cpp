#include "voxel/vegetation.h"

#include <algorithm>

#include "voxel/column_sweep.h"

namespace ground_filter {
namespace voxel {

void VegetationRule::stats(const VoxelGroundFilterParams& p, const VoxelGrid& g, const float* h0,
                           const std::uint8_t* ground, std::size_t c0, std::size_t c1) {
  const float hmin = static_cast<float>(p.veg_min_height);
  const float hmax = static_cast<float>(p.veg_max_height);
  const std::uint32_t* cf = g.col_first.data();
  const std::uint32_t* vs = g.vstart.data();
  const std::uint32_t* pvox = g.pvox.data();
  const float* vz = g.vz.data();
  std::uint8_t* vg = voxel_has_ground_.data();
  std::uint64_t* clutter = clutter_.data();
  std::uint8_t* has_ground = has_ground_.data();
  // Flat passes over points, then voxels (voxels hold 1-2 points and columns 1-2 voxels on
  // average: loops per voxel or per column mispredict their exits).
  const std::uint32_t v0 = cf[c0], v1 = cf[c1];
  std::fill(vg + v0, vg + v1, std::uint8_t{0});
  for (std::uint32_t k = vs[v0]; k < vs[v1]; ++k) vg[pvox[k]] |= ground[k];
  std::size_t col = c0;
  std::uint64_t acc = 0;
  std::uint8_t any = 0;
  for (std::uint32_t v = v0; v < v1; ++v) {
    const bool next = v == cf[col + 1];
    col += next;
    acc = next ? 0 : acc;
    any = next ? 0 : any;
    const float h = vz[v] - h0[v];  // centroid over the cell plane
    const bool in = h >= hmin && h <= hmax;
    acc += in ? (static_cast<std::uint64_t>(vs[v + 1] - vs[v]) << 32 | 1u) : 0u;
    any |= vg[v];
    clutter[col] = acc;
    has_ground[col] = any;
  }
}

void VegetationRule::relabel(const VoxelGroundFilterParams& p, const VoxelGrid& g,
                             const GroundModelResult& model, int t, int range,
                             std::uint8_t* ground) {
  const std::int32_t none = static_cast<std::int32_t>(g.columns());
  const int r = p.veg_radius;
  const int w = 2 * r + 1;
  const std::uint64_t min_n = static_cast<std::uint64_t>(p.veg_min_points);
  const double max_density = p.veg_max_density;
  const float base = static_cast<float>(p.veg_min_base);
  const int y_bits = g.shift_x - g.shift_y;
  const std::uint64_t y_mask = g.mask_y;
  const std::uint64_t* ck = g.col_key.data();
  const std::uint64_t* cl = clutter_.data();
  // w dense rows of column ids (row x in slot x mod w; entry y + r is column y), each filled
  // once however many columns read it.
  const std::size_t stride = g.ny + 2 * static_cast<std::size_t>(r);
  std::vector<std::int32_t>& rows = id_rows_[t];
  rows.assign(static_cast<std::size_t>(w) * stride, none);
  std::vector<std::int64_t>& held = held_[t];
  held.assign(static_cast<std::size_t>(w), -1);
  auto load = [&](std::int64_t x) {  // x >= 0
    const std::size_t s = static_cast<std::size_t>(x % w);
    if (held[s] == x) return;
    std::int32_t* row = rows.data() + s * stride + r;
    if (held[s] >= 0) {
      for (std::uint32_t q = row_first_[held[s]]; q < row_first_[held[s] + 1]; ++q) {
        row[ck[q] & y_mask] = none;
      }
    }
    if (static_cast<std::uint64_t>(x) < g.nx) {
      for (std::uint32_t q = row_first_[x]; q < row_first_[x + 1]; ++q) {
        row[ck[q] & y_mask] = static_cast<std::int32_t>(q);
      }
    }
    held[s] = x;
  };
  std::int64_t loaded = -1;             // row whose window is in the buffers
  const std::int32_t* win[2 * 10 + 1];  // the window's rows (veg_radius <= 10)
  int nrows = 0;
  for (std::size_t q = bounds_[range]; q < bounds_[range + 1]; ++q) {
    const std::int64_t x = static_cast<std::int64_t>(ck[q] >> y_bits);
    if (x != loaded) {
      nrows = 0;
      for (std::int64_t xr = std::max<std::int64_t>(0, x - r); xr <= x + r; ++xr) {
        load(xr);
        win[nrows++] = rows.data() + static_cast<std::size_t>(xr % w) * stride;
      }
      loaded = x;
    }
    // Clutter points and voxels of the window (packed, one sum).
    const std::size_t y = ck[q] & y_mask;
    std::uint64_t sum = 0;
    for (int i = 0; i < nrows; ++i) {
      const std::int32_t* row = win[i] + y;
      for (int j = 0; j < w; ++j) sum += cl[row[j]];
    }
    // Every column's window is summed (a test per column first would mispredict).
    const std::uint64_t n = sum >> 32, nv = sum & 0xFFFFFFFFu;
    if (!has_ground_[q] || n < min_n) continue;
    if (max_density > 0.0 && static_cast<double>(n) > max_density * static_cast<double>(nv)) {
      continue;
    }
    // Only points above the model's surface: clutter bases, not the ground under them.
    for (std::uint32_t v = g.col_first[q]; v < g.col_first[q + 1]; ++v) {
      const HeightPlane& hp = model.plane(g.vcell[v]);
      for (std::uint32_t k = g.vstart[v]; k < g.vstart[v + 1]; ++k) {
        const float* pt = g.xyz(k);
        if (pt[2] - static_cast<float>(hp.at(pt[0], pt[1])) >= base) ground[k] = 0;
      }
    }
  }
}

void VegetationRule::run(const VoxelGroundFilterParams& p, const VoxelGrid& g,
                         const GroundModelResult& model, int threads, WorkerPool* pool,
                         ClassifyResult* cls) {
  std::vector<std::uint8_t>* ground = &cls->ground;
  const std::size_t ncol = g.columns();
  clutter_.resize(ncol + 1);
  has_ground_.resize(ncol);
  voxel_has_ground_.resize(g.voxels());
  clutter_[ncol] = 0;
  const int nt = threads > 1 && g.points() >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;
  const std::uint8_t* labels = ground->data();
  const float* h0 = cls->plane_height.data();
  pool->run(nt, nch,
            [&](int, int c) { stats(p, g, h0, labels, ncol * c / nch, ncol * (c + 1) / nch); });
  // First column of each row x (size nx + 1).
  const int y_bits = g.shift_x - g.shift_y;
  row_first_.assign(g.nx + 1, 0);
  for (std::size_t q = 0; q < ncol; ++q) ++row_first_[(g.col_key[q] >> y_bits) + 1];
  for (std::uint64_t x = 0; x < g.nx; ++x) row_first_[x + 1] += row_first_[x];
  splitRows(g, nch, &bounds_);
  id_rows_.resize(static_cast<std::size_t>(nt));
  held_.resize(static_cast<std::size_t>(nt));
  const std::size_t w = 2 * static_cast<std::size_t>(p.veg_radius) + 1;
  for (int t = 0; t < nt; ++t) {  // here: a worker may first run a chunk in a later scan
    id_rows_[t].reserve(w * (g.ny + w - 1));
    held_[t].reserve(w);
  }
  // Columns are relabelled from the counts only, never from labels another range rewrites.
  std::uint8_t* out = ground->data();
  pool->run(nt, nch, [&](int t, int c) { relabel(p, g, model, t, c, out); });
}

}  // namespace voxel
}  // namespace ground_filter
