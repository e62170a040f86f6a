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
  const float base = static_cast<float>(p.veg_min_base);
  const std::size_t ncol = g.columns();
  const std::int32_t none = static_cast<std::int32_t>(ncol);
  const float vs = static_cast<float>(p.voxel_size);
  const float min_n = static_cast<float>(p.veg_min_points);
  const float max_gap = static_cast<float>(p.veg_max_gap);
  const float max_density = static_cast<float>(p.veg_max_density);
  const float min_var = static_cast<float>(p.veg_min_spread * p.veg_min_spread);
  const Above* ab = above_.data();
  sweepColumns(
      g, bounds_[range], bounds_[range + 1], &id_rows_[t], none,
      [&](std::int32_t* row, std::size_t q) {
        row[(g.col_key[q] & g.mask_y) + 1] = static_cast<std::int32_t>(q);
      },
      [&](std::int32_t* row, std::size_t q) { row[(g.col_key[q] & g.mask_y) + 1] = none; },
      [&](std::size_t q, const std::int32_t* e0, const std::int32_t* e1, const std::int32_t* e2) {
        const std::int32_t* rows[3] = {e0, e1, e2};
        // The 9 columns' moments, moved to the centre of column q.
        float n = 0, nv = 0, hlo = kNoHeight, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
        for (int i = 0; i < 3; ++i) {
          for (int j = 0; j < 3; ++j) {
            const Above& a = ab[rows[i][j]];
            if (a.n == 0.f) continue;
            const float ox = static_cast<float>(i - 1) * vs, oy = static_cast<float>(j - 1) * vs;
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
        if (n < min_n || n == 0.f || hlo > max_gap) return;
        if (max_density > 0.f && n > max_density * nv) return;
        if (min_var > 0.f) {
          // Smallest eigenvalue of the horizontal covariance: the thickness of a sheet.
          const float mx = sx / n, my = sy / n;
          const float cxx = sxx / n - mx * mx, cyy = syy / n - my * my, cxy = sxy / n - mx * my;
          const float half = 0.5f * (cxx - cyy);
          const float lmin = 0.5f * (cxx + cyy) - std::sqrt(half * half + cxy * cxy);
          if (lmin < min_var) return;
        }
        // Only points above the model's surface: clutter bases, not the ground under them.
        for (std::uint32_t v = g.col_first[q]; v < g.col_first[q + 1]; ++v) {
          const HeightPlane& hp = model.plane(g.vcell[v]);
          for (std::uint32_t k = g.vstart[v]; k < g.vstart[v + 1]; ++k) {
            if (g.sz[k] - static_cast<float>(hp.at(g.sx[k], g.sy[k])) >= base) ground[k] = 0;
          }
        }
      });
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
  splitRows(g, nch, &bounds_);
  id_rows_.resize(static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) id_rows_[t].reserve(3 * (g.ny + 2));
  std::uint8_t* out = ground->data();
  pool->run(nt, nch, [&](int t, int c) { relabel(p, g, model, t, c, out); });
}

}  // namespace voxel
}  // namespace ground_filter
