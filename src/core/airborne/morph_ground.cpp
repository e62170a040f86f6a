#include "airborne/morph_ground.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ground_filter {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
// Gauss-Seidel sweeps of the gap filling after the ring-by-ring start (enough to smooth the
// rings; the surface far inside a wide gap matters little, the opening is taken over it).
constexpr int kFillSweeps = 50;

// Widens the sliding minimum of every row by one cell on each side: the minimum over
// [x - w, x + w] is the minimum of those over [x - 1 - (w - 1), x - 1 + (w - 1)] and
// [x + 1 - (w - 1), x + 1 + (w - 1)]; cells outside the row do not count. Each row is copied
// between two kInf sentinels first (`pad`, nx + 2 floats), so the loop reads the old values
// only and the compiler vectorises it (the in-place form carried the old value in a register
// from one cell to the next and stayed scalar).
void widenRowMin(float* t, int nx, int ny, float* pad) {
  pad[0] = kInf;
  pad[nx + 1] = kInf;
  for (int y = 0; y < ny; ++y) {
    float* row = t + static_cast<std::size_t>(y) * nx;
    std::copy(row, row + nx, pad + 1);
    for (int x = 0; x < nx; ++x) row[x] = std::min(pad[x + 1], std::min(pad[x], pad[x + 2]));
  }
}

}  // namespace

void MorphGround::erode(const std::vector<float>& in, int r, bool dilate, std::vector<float>* out) {
  // A disk of radius r is a stack of rows: row dy is a segment of half-width
  // w(dy) = floor(sqrt(r^2 - dy^2)). Going from dy = r to 0, w only grows, so the row minima of
  // half-width w(dy) come from widening the previous ones (2 comparisons a cell per step).
  // Dilation = erosion of the negated raster.
  const std::size_t n = in.size();
  tmp_.resize(n);
  pad_.resize(static_cast<std::size_t>(nx_) + 2);
  for (std::size_t i = 0; i < n; ++i) tmp_[i] = dilate ? -in[i] : in[i];
  out->assign(n, kInf);
  float* o = out->data();
  int w = 0;
  for (int dy = r; dy >= 0; --dy) {
    const int want = static_cast<int>(std::floor(std::sqrt(static_cast<double>(r * r - dy * dy))));
    for (; w < want; ++w) widenRowMin(tmp_.data(), nx_, ny_, pad_.data());
    for (int y = 0; y < ny_; ++y) {
      float* oy = o + static_cast<std::size_t>(y) * nx_;
      for (int sgn = -1; sgn <= 1; sgn += 2) {
        const int ys = y + sgn * dy;
        if (ys < 0 || ys >= ny_ || (dy == 0 && sgn > 0)) continue;
        const float* t = tmp_.data() + static_cast<std::size_t>(ys) * nx_;
        for (int x = 0; x < nx_; ++x) oy[x] = std::min(oy[x], t[x]);
      }
    }
  }
  if (dilate) {
    for (std::size_t i = 0; i < n; ++i) o[i] = -o[i];
  }
}

void MorphGround::fill(std::vector<float>* zp) {
  // Gaps (no return, or cells dropped as objects) get the mean of their known 4-neighbours,
  // ring by ring from the known cells, then Gauss-Seidel sweeps of Laplace's equation over the
  // gap cells (a smooth surface between the known ones, like SMRF's inpainting).
  std::vector<float>& z = *zp;
  const std::size_t n = z.size();
  known_.assign(n, 0);
  frontier_.clear();
  std::size_t unknown = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isnan(z[i])) {
      ++unknown;
    } else {
      known_[i] = 1;
    }
  }
  if (unknown == 0 || unknown == n) return;
  auto neighbourMean = [&](std::int32_t i, bool only_known, float* v) {
    double s = 0.0;
    int c = 0;
    forNeighbours(i, [&](std::int32_t j) {
      if (only_known && !known_[j]) return;
      s += z[j];
      ++c;
    });
    if (c == 0) return false;
    *v = static_cast<float>(s / c);
    return true;
  };
  // Gap cells in index order (the sweeps' order); a cell on the raster's border is stored as
  // ~index (negative), so the sweeps tell the two apart without a division per cell.
  gaps_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (known_[i]) continue;
    const int x = static_cast<int>(i % nx_), y = static_cast<int>(i / nx_);
    const bool inner = x > 0 && y > 0 && x + 1 < nx_ && y + 1 < ny_;
    gaps_.push_back(inner ? static_cast<std::int32_t>(i) : ~static_cast<std::int32_t>(i));
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (known_[i]) continue;
    float v;
    if (neighbourMean(static_cast<std::int32_t>(i), true, &v)) {
      frontier_.push_back(static_cast<std::int32_t>(i));
    }
  }
  std::vector<float>& vals = fill_vals_;  // kept: no allocation per scan
  while (!frontier_.empty()) {
    vals.resize(frontier_.size());
    for (std::size_t f = 0; f < frontier_.size(); ++f) {
      neighbourMean(frontier_[f], true, &vals[f]);
    }
    next_.clear();
    for (std::size_t f = 0; f < frontier_.size(); ++f) {
      z[frontier_[f]] = vals[f];
      known_[frontier_[f]] = 1;
    }
    for (std::size_t f = 0; f < frontier_.size(); ++f) {
      forNeighbours(frontier_[f], [&](std::int32_t j) {
        if (!known_[j]) {
          known_[j] = 2;  // queued once
          next_.push_back(j);
        }
      });
    }
    for (std::int32_t j : next_) known_[j] = 0;
    frontier_.swap(next_);
  }
  float* zz = z.data();
  for (int sweep = 0; sweep < kFillSweeps; ++sweep) {
    for (const std::int32_t g : gaps_) {
      if (g >= 0) {
        zz[g] = 0.25f * (zz[g - 1] + zz[g + 1] + zz[g - nx_] + zz[g + nx_]);
      } else {
        const std::int32_t i = ~g;
        float v;
        if (neighbourMean(i, false, &v)) zz[i] = v;
      }
    }
  }
}

void MorphGround::openObjects(const MorphGroundSettings& s, double c, int rmax,
                              const std::vector<float>* allow, std::vector<std::uint8_t>* object) {
  // A cell that an opening of radius r lowers by more than the terrain could drop over r
  // (allowed slope x r) lies on an object.
  const std::size_t n = zfill_.size();
  object->assign(n, 0);
  std::vector<float>& last = dem_;
  last = zfill_;
  for (int r = 1; r <= rmax; ++r) {
    erode(last, r, false, &eroded_);
    erode(eroded_, r, true, &opened_);
    const float rc = static_cast<float>(r * c);
    const float thr = static_cast<float>(s.slope) * rc;
    std::uint8_t* o = object->data();
    if (allow == nullptr) {
      for (std::size_t i = 0; i < n; ++i) {
        if (last[i] - opened_[i] > thr) o[i] = 1;
      }
    } else {
      const float* a = allow->data();
      for (std::size_t i = 0; i < n; ++i) {
        if (last[i] - opened_[i] > std::max(thr, a[i] * rc)) o[i] = 1;
      }
    }
    last.swap(opened_);
  }
}

void MorphGround::surfaceWithoutObjects() {
  // The minimum raster without object cells, gaps filled.
  const std::size_t n = zmin_.size();
  dem_ = zmin_;
  for (std::size_t i = 0; i < n; ++i) {
    if (object_[i]) dem_[i] = std::numeric_limits<float>::quiet_NaN();
  }
  fill(&dem_);
  if (std::isnan(dem_[0])) {  // every cell an object: fall back to the minimum raster
    dem_ = zmin_;
    fill(&dem_);
  }
}

void MorphGround::terrainSlope(double c, int w) {
  // Slope of the provisional surface towards +-w cells (clamped at the border), the steeper
  // side per axis: the terrain's slope at the scale of the largest object the opening removes
  // (one-sided, so a symmetric crest, where a central difference is 0, gets its flanks' slope).
  tslope_.assign(dem_.size(), 0.0f);
  const float* d = dem_.data();
  auto side = [c](float a, float b, int cells) {
    return cells > 0 ? std::fabs(a - b) / (cells * c) : 0.0;
  };
  for (int y = 0; y < ny_; ++y) {
    const int ya = std::max(0, y - w), yb = std::min(ny_ - 1, y + w);
    for (int x = 0; x < nx_; ++x) {
      const int xa = std::max(0, x - w), xb = std::min(nx_ - 1, x + w);
      const float z = d[y * nx_ + x];
      const double gx = 0.5 * (side(d[y * nx_ + xb], z, xb - x) + side(z, d[y * nx_ + xa], x - xa));
      const double gy = 0.5 * (side(d[yb * nx_ + x], z, yb - y) + side(z, d[ya * nx_ + x], y - ya));
      tslope_[static_cast<std::size_t>(y) * nx_ + x] = static_cast<float>(std::hypot(gx, gy));
    }
  }
}

void MorphGround::joinTerrain(const MorphGroundSettings& s, double c) {
  // object1_: the first pass's objects, object_: the second's. Flood from the first pass's
  // terrain through the cells only the second pass keeps, over steps of at most
  // max(slope, terrain slope) x cell between the (gap-filled) minima; what the flood does not
  // reach stays an object.
  const std::size_t n = object_.size();
  known_.assign(n, 0);  // reached
  frontier_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (!object1_[i]) {
      known_[i] = 1;
      frontier_.push_back(static_cast<std::int32_t>(i));
    }
  }
  for (std::size_t head = 0; head < frontier_.size(); ++head) {
    const std::int32_t i = frontier_[head];
    forNeighbours(i, [&](std::int32_t j) {
      if (known_[j] || object_[j]) return;
      const double step = std::max(s.slope, static_cast<double>(tslope_[j])) * c;
      if (std::fabs(zfill_[j] - zfill_[i]) > step) return;
      known_[j] = 1;
      frontier_.push_back(j);
    });
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (object1_[i] && !known_[i]) object_[i] = 1;
  }
}

bool MorphGround::aloneAtItsHeight(const CloudView& cloud, double c, int x, int y,
                                   std::int32_t m) const {
  const int ra = static_cast<int>(std::ceil(kLowOutlier.alone / c));
  const double ra2 = kLowOutlier.alone * kLowOutlier.alone;
  const double mx = cloud.x(m), my = cloud.y(m), mz = cloud.z(m);
  for (int yy = std::max(0, y - ra); yy <= std::min(ny_ - 1, y + ra); ++yy) {
    for (int xx = std::max(0, x - ra); xx <= std::min(nx_ - 1, x + ra); ++xx) {
      const std::size_t kk = static_cast<std::size_t>(yy) * nx_ + xx;
      for (std::int32_t a = cell_start_[kk]; a < cell_start_[kk + 1]; ++a) {
        const std::int32_t o = cell_pts_[a];
        const double dx = cloud.x(o) - mx, dy = cloud.y(o) - my;
        if (o != m && dx * dx + dy * dy <= ra2 && cloud.z(o) - mz < kLowOutlier.drop) return false;
      }
    }
  }
  return true;
}

void MorphGround::dropLowOutliers(const CloudView& cloud, double c) {
  // A cell's lowest return with at least kLowOutlier.min_neighbours other returns within
  // kLowOutlier.radius (horizontally) and none of them less than kLowOutlier.drop above it lies on
  // no surface: terrain, however steep, has returns near the lowest one. The cell's minimum
  // becomes its next-lowest return (a gap when it had none); the outlier itself, far below the
  // surface, is then labelled non-ground by the height test. Points are bucketed by cell first.
  const std::size_t n = zmin_.size(), np = cell_of_.size();
  cell_start_.assign(n + 1, 0);
  for (std::size_t i = 0; i < np; ++i) {
    if (cell_of_[i] >= 0) ++cell_start_[static_cast<std::size_t>(cell_of_[i]) + 1];
  }
  for (std::size_t k = 0; k < n; ++k) cell_start_[k + 1] += cell_start_[k];
  cell_pts_.resize(static_cast<std::size_t>(cell_start_[n]));
  next_.assign(cell_start_.begin(), cell_start_.end() - 1);  // fill position per cell
  for (std::size_t i = 0; i < np; ++i) {
    if (cell_of_[i] >= 0) cell_pts_[next_[cell_of_[i]]++] = static_cast<std::int32_t>(i);
  }
  const int rc = static_cast<int>(std::ceil(kLowOutlier.radius / c));
  const double r2 = kLowOutlier.radius * kLowOutlier.radius;
  // Cells within +-rs lie wholly within the radius of any point of the centre cell.
  const int rs =
      std::max(0, static_cast<int>(std::floor(kLowOutlier.radius / (c * std::sqrt(2.0)))) - 1);
  gaps_.clear();  // the cells whose minimum is an outlier
  for (int y = 0; y < ny_; ++y) {
    for (int x = 0; x < nx_; ++x) {
      const std::size_t k = static_cast<std::size_t>(y) * nx_ + x;
      if (cell_start_[k] == cell_start_[k + 1]) continue;
      std::int32_t m = cell_pts_[cell_start_[k]];
      for (std::int32_t a = cell_start_[k] + 1; a < cell_start_[k + 1]; ++a) {
        if (cloud.z(cell_pts_[a]) < cloud.z(m)) m = cell_pts_[a];
      }
      const double mx = cloud.x(m), my = cloud.y(m), mz = cloud.z(m);
      int count = 0;
      bool near = false;
      // Shortcut: a neighbour cell lying wholly within the radius whose minimum is near.
      for (int dy = -rs; dy <= rs && !near; ++dy) {
        for (int dx = -rs; dx <= rs && !near; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= nx_ || yy >= ny_) continue;
          near = zmin_[static_cast<std::size_t>(yy) * nx_ + xx] - mz < kLowOutlier.drop;  // NaN: no
        }
      }
      for (int yy = std::max(0, y - rc); yy <= std::min(ny_ - 1, y + rc) && !near; ++yy) {
        for (int xx = std::max(0, x - rc); xx <= std::min(nx_ - 1, x + rc) && !near; ++xx) {
          const std::size_t kk = static_cast<std::size_t>(yy) * nx_ + xx;
          for (std::int32_t a = cell_start_[kk]; a < cell_start_[kk + 1]; ++a) {
            const std::int32_t o = cell_pts_[a];
            const double dx = cloud.x(o) - mx, dy = cloud.y(o) - my;
            if (o == m || dx * dx + dy * dy > r2) continue;
            ++count;
            if (cloud.z(o) - mz < kLowOutlier.drop) {
              near = true;
              break;
            }
          }
        }
      }
      if (near || count < kLowOutlier.min_neighbours) continue;
      if (!aloneAtItsHeight(cloud, c, x, y, m)) continue;
      gaps_.push_back(static_cast<std::int32_t>(k));
    }
  }
  for (const std::int32_t k : gaps_) {  // the next-lowest return, NaN when there is none
    float lo = kInf, lo2 = kInf;
    for (std::int32_t a = cell_start_[k]; a < cell_start_[k + 1]; ++a) {
      const float z = cloud.z(cell_pts_[a]);
      if (z < lo) {
        lo2 = lo;
        lo = z;
      } else if (z < lo2) {
        lo2 = z;
      }
    }
    zmin_[k] = lo2 < kInf ? lo2 : std::numeric_limits<float>::quiet_NaN();
  }
}

std::size_t MorphGround::run(const CloudView& cloud, const MorphGroundSettings& s,
                             std::vector<std::uint8_t>* labels) {
  const std::size_t np = cloud.size();
  labels->assign(np, 0);
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  std::size_t valid = 0;
  for (std::size_t i = 0; i < np; ++i) {
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) continue;
    ++valid;
    x0 = std::min(x0, static_cast<double>(x));
    x1 = std::max(x1, static_cast<double>(x));
    y0 = std::min(y0, static_cast<double>(y));
    y1 = std::max(y1, static_cast<double>(y));
  }
  if (valid == 0) return 0;
  double c = s.cell;
  auto cellsFor = [&](double cc) {
    return (std::floor((x1 - x0) / cc) + 1.0) * (std::floor((y1 - y0) / cc) + 1.0);
  };
  // A raster with many more cells than points is mostly filled gaps and costs time for nothing
  // (the opening runs over every cell): a few stray points or one far outlier would otherwise
  // grow it to kMaxCells. The sparsest dev tiles have 6.4 cells a point at 1 m cells.
  const double max_cells = std::min(
      static_cast<double>(kMaxCells),
      std::max(static_cast<double>(kMinCells), kMaxCellsPerPoint * static_cast<double>(valid)));
  while (cellsFor(c) > max_cells) c *= 1.25;
  nx_ = static_cast<int>(std::floor((x1 - x0) / c)) + 1;
  ny_ = static_cast<int>(std::floor((y1 - y0) / c)) + 1;
  const std::size_t n = static_cast<std::size_t>(nx_) * ny_;

  // 1. Minimum-elevation raster.
  zmin_.assign(n, std::numeric_limits<float>::quiet_NaN());
  cell_of_.assign(np, -1);
  for (std::size_t i = 0; i < np; ++i) {
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) continue;
    const int ix = std::min(nx_ - 1, static_cast<int>((x - x0) / c));
    const int iy = std::min(ny_ - 1, static_cast<int>((y - y0) / c));
    const std::int32_t cell = iy * nx_ + ix;
    cell_of_[i] = cell;
    if (!(zmin_[cell] <= z)) zmin_[cell] = z;  // NaN compares false: first point wins
  }
  // 1b. Low outliers (multipath and other returns below the terrain) would pit the surface.
  dropLowOutliers(cloud, c);
  zfill_ = zmin_;
  fill(&zfill_);

  // 2. Progressive opening with SMRF's slope allowance everywhere, 3. provisional surface.
  const int rmax = std::max(1, static_cast<int>(std::ceil(s.window / c)));
  openObjects(s, c, rmax, nullptr, &object_);
  surfaceWithoutObjects();

  // 3b. Steep terrain. An opening lowers a planar slope by nothing but cuts a convex break
  //     (a ridge, a quarry edge, the top of a steep bank) by about the terrain slope x r, so
  //     where the terrain is steeper than `slope` SMRF calls its breaks objects. Second pass:
  //     the allowance per cell is the terrain's own slope (the provisional surface's, across the
  //     largest window, wider than the objects it removed), at least `slope`. A cell that only
  //     this pass keeps counts as terrain only when it joins the first pass's terrain through
  //     cells whose minima differ by no more than that slope allows over one cell: a terrain
  //     break is continuous, a roof or a crown on a slope stands above its surroundings.
  terrainSlope(c, rmax);
  object1_.clear();  // the first opening's objects, kept below only where the steep pass runs
  if (*std::max_element(tslope_.begin(), tslope_.end()) > s.slope) {
    //     The provisional surface is flattened where the first pass cut a crest, so the slope
    //     measured there is too low; a later pass measures it again on the last pass's surface
    //     (stopping early when no cell changed).
    object1_.swap(object_);
    for (int pass = 0; pass < kSteepPasses; ++pass) {
      if (pass > 0) {
        terrainSlope(c, rmax);
        prev_object_ = object_;
      }
      openObjects(s, c, rmax, &tslope_, &object_);
      joinTerrain(s, c);
      surfaceWithoutObjects();
      if (pass > 0 && object_ == prev_object_) break;
    }
  }

  // 3c. Roofs wider than the opening: flat regions that stand on walls all round.
  dropWalledRoofs(c, rmax);

  // 4. Gradient magnitude (central differences, one-sided at the border).
  grad_.assign(n, 0.0f);
  for (int y = 0; y < ny_; ++y) {
    for (int x = 0; x < nx_; ++x) {
      const int xa = std::max(0, x - 1), xb = std::min(nx_ - 1, x + 1);
      const int ya = std::max(0, y - 1), yb = std::min(ny_ - 1, y + 1);
      const float* d = dem_.data();
      const double gx = xb > xa ? (d[y * nx_ + xb] - d[y * nx_ + xa]) / ((xb - xa) * c) : 0.0;
      const double gy = yb > ya ? (d[yb * nx_ + x] - d[ya * nx_ + x]) / ((yb - ya) * c) : 0.0;
      grad_[static_cast<std::size_t>(y) * nx_ + x] = static_cast<float>(std::hypot(gx, gy));
    }
  }

  // 5. Per point: distance to the bilinear surface through the cell centres.
  for (std::size_t i = 0; i < np; ++i) {
    if (cell_of_[i] < 0) continue;
    const double fx = (cloud.x(i) - x0) / c - 0.5, fy = (cloud.y(i) - y0) / c - 0.5;
    const int ia = std::max(0, std::min(nx_ - 1, static_cast<int>(std::floor(fx))));
    const int ja = std::max(0, std::min(ny_ - 1, static_cast<int>(std::floor(fy))));
    const int ib = std::min(nx_ - 1, ia + 1), jb = std::min(ny_ - 1, ja + 1);
    const double tx = std::max(0.0, std::min(1.0, fx - ia));
    const double ty = std::max(0.0, std::min(1.0, fy - ja));
    const float* d = dem_.data();
    const double zs = d[ja * nx_ + ia] * (1 - tx) * (1 - ty) + d[ja * nx_ + ib] * tx * (1 - ty) +
                      d[jb * nx_ + ia] * (1 - tx) * ty + d[jb * nx_ + ib] * tx * ty;
    const double limit = s.threshold + s.scale * grad_[cell_of_[i]];
    (*labels)[i] = std::fabs(cloud.z(i) - zs) <= limit ? 1 : 0;
  }
  return valid;
}

}  // namespace ground_filter
