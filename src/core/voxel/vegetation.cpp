#include "voxel/vegetation.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "voxel/column_sweep.h"

namespace ground_filter {
namespace voxel {

namespace {

constexpr float kNoHeight = std::numeric_limits<float>::max();
constexpr VegetationRule::Above kNone{0.f, 0.f, kNoHeight, 0.f, 0.f, 0.f, 0.f, 0.f};

}  // namespace

void VegetationRule::stats(const VoxelGroundFilterParams& p, const VoxelGrid& g,
                           const GroundModel& model, std::size_t c0, std::size_t c1) {
  const float vs = static_cast<float>(p.voxel_size);
  const float hmin = static_cast<float>(p.veg_min_height);
  const float hmax = static_cast<float>(p.veg_max_height);
  const int y_bits = g.shift_x - g.shift_y;
  for (std::size_t q = c0; q < c1; ++q) {
    Above a = kNone;
    // Column centre (voxel indices count from the cloud's min corner, like sx, sy).
    const float cx = (static_cast<float>(g.col_key[q] >> y_bits) + 0.5f) * vs;
    const float cy = (static_cast<float>(g.col_key[q] & g.mask_y) + 0.5f) * vs;
    for (std::uint32_t v = g.col_first[q]; v < g.col_first[q + 1]; ++v) {
      const HeightPlane& hp = model.plane(g.vcell[v]);
      const float n0 = a.n;
      for (std::uint32_t k = g.vstart[v]; k < g.vstart[v + 1]; ++k) {
        const float h = g.sz[k] - static_cast<float>(hp.at(g.sx[k], g.sy[k]));
        if (h < hmin || h > hmax) continue;
        const float dx = g.sx[k] - cx, dy = g.sy[k] - cy;
        a.n += 1.f;
        a.hlo = std::min(a.hlo, h);
        a.x += dx;
        a.y += dy;
        a.xx += dx * dx;
        a.yy += dy * dy;
        a.xy += dx * dy;
      }
      a.nv += a.n > n0 ? 1.f : 0.f;
    }
    above_[q] = a;
  }
}

void VegetationRule::relabel(const VoxelGroundFilterParams& p, const VoxelGrid& g,
                             const GroundModel& model, int t, int range, std::uint8_t* ground) {
  const std::size_t ncol = g.columns();
  const std::int32_t none = static_cast<std::int32_t>(ncol);
  const int r = p.veg_radius;
  const int w = 2 * r + 1;
  const float vs = static_cast<float>(p.voxel_size);
  const float min_n = static_cast<float>(p.veg_min_points);
  const float max_gap = static_cast<float>(p.veg_max_gap);
  const float max_density = static_cast<float>(p.veg_max_density);
  const float min_var = static_cast<float>(p.veg_min_spread * p.veg_min_spread);
  const float base = static_cast<float>(p.veg_min_base);
  const int y_bits = g.shift_x - g.shift_y;
  const std::uint64_t y_mask = g.mask_y;
  const std::uint64_t* ck = g.col_key.data();
  const Above* ab = above_.data();
  // w dense rows of column ids (row x in slot x mod w; entry y + r is column y), each filled
  // once however many columns read it.
  const std::size_t stride = g.ny + 2 * static_cast<std::size_t>(r);
  std::vector<std::int32_t>& rows = id_rows_[t];
  rows.assign(static_cast<std::size_t>(w) * stride, none);
  std::vector<std::int64_t>& held = held_[t];
  held.assign(static_cast<std::size_t>(w), -1);
  auto slotOf = [&](std::int64_t x) { return static_cast<std::size_t>(x % w); };
  auto load = [&](std::int64_t x) {  // x >= 0
    const std::size_t s = slotOf(x);
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
  for (std::size_t q = bounds_[range]; q < bounds_[range + 1]; ++q) {
    const std::int64_t x = static_cast<std::int64_t>(ck[q] >> y_bits);
    const std::size_t y = ck[q] & y_mask;
    if (q == bounds_[range] || ck[q - 1] >> y_bits != ck[q] >> y_bits) {
      for (std::int64_t xr = x - r; xr <= x + r; ++xr) {
        if (xr >= 0) load(xr);
      }
    }
    // The window's moments, moved to the centre of column q.
    float n = 0, nv = 0, hlo = kNoHeight, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    for (int i = -r; i <= r; ++i) {
      if (x + i < 0) continue;
      const std::int32_t* row = rows.data() + slotOf(x + i) * stride + y;  // entry y + r = y
      const float ox = static_cast<float>(i) * vs;
      for (int j = -r; j <= r; ++j) {
        const Above& a = ab[row[j + r]];
        if (a.n == 0.f) continue;
        const float oy = static_cast<float>(j) * vs;
        n += a.n;
        nv += a.nv;
        hlo = std::min(hlo, a.hlo);
        sx += a.x + a.n * ox;
        sy += a.y + a.n * oy;
        sxx += a.xx + 2.f * ox * a.x + a.n * ox * ox;
        syy += a.yy + 2.f * oy * a.y + a.n * oy * oy;
        sxy += a.xy + ox * a.y + oy * a.x + a.n * ox * oy;
      }
    }
    if (n < min_n || n == 0.f || hlo > max_gap) continue;
    if (max_density > 0.f && n > max_density * nv) continue;
    if (min_var > 0.f) {
      // Smallest eigenvalue of the horizontal covariance: the thickness of a sheet.
      const float mx = sx / n, my = sy / n;
      const float cxx = sxx / n - mx * mx, cyy = syy / n - my * my, cxy = sxy / n - mx * my;
      const float half = 0.5f * (cxx - cyy);
      const float lmin = 0.5f * (cxx + cyy) - std::sqrt(half * half + cxy * cxy);
      if (lmin < min_var) continue;
    }
    // Only points above the model's surface: clutter bases, not the ground under them.
    for (std::uint32_t v = g.col_first[q]; v < g.col_first[q + 1]; ++v) {
      const HeightPlane& hp = model.plane(g.vcell[v]);
      for (std::uint32_t k = g.vstart[v]; k < g.vstart[v + 1]; ++k) {
        if (g.sz[k] - static_cast<float>(hp.at(g.sx[k], g.sy[k])) >= base) ground[k] = 0;
      }
    }
  }
}

void VegetationRule::run(const VoxelGroundFilterParams& p, const VoxelGrid& g,
                         const GroundModel& model, int threads, WorkerPool* pool,
                         std::vector<std::uint8_t>* ground) {
  const std::size_t ncol = g.columns();
  above_.resize(ncol + 1);
  above_[ncol] = kNone;
  const int nt = threads > 1 && g.points() >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;
  pool->run(nt, nch, [&](int, int c) { stats(p, g, model, ncol * c / nch, ncol * (c + 1) / nch); });
  // First column of each row x (size nx + 1).
  const int y_bits = g.shift_x - g.shift_y;
  row_first_.assign(g.nx + 1, 0);
  for (std::size_t q = 0; q < ncol; ++q) ++row_first_[(g.col_key[q] >> y_bits) + 1];
  for (std::uint64_t x = 0; x < g.nx; ++x) row_first_[x + 1] += row_first_[x];
  splitRows(g, nch, &bounds_);
  id_rows_.resize(static_cast<std::size_t>(nt));
  held_.resize(static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) {  // here: a worker may first run a chunk in a later scan
    id_rows_[t].reserve(static_cast<std::size_t>(2 * p.veg_radius + 1) *
                        (g.ny + 2 * static_cast<std::size_t>(p.veg_radius)));
    held_[t].reserve(static_cast<std::size_t>(2 * p.veg_radius + 1));
  }
  std::uint8_t* out = ground->data();
  pool->run(nt, nch, [&](int t, int c) { relabel(p, g, model, t, c, out); });
}

}  // namespace voxel
}  // namespace ground_filter
