// Ground surface from a filter's ground labels and the height of points above it
// (include/ground_filter/height_above_ground.h, docs/height_above_ground.md).

#include "ground_filter/height_above_ground.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

namespace ground_filter {

constexpr std::size_t GroundSurfaceParams::kMaxCells;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
// A plane's slope is fitted along a direction only where the cell's points spread along it by
// at least this share of the cell edge (standard deviation); elsewhere the slope is 0.
constexpr double kMinSpreadShare = 0.1;
constexpr double kMaxSlope = 1.5;       // steeper fits fall back to the mean (no slope) [m/m]
constexpr double kRefitRms = 0.02;      // cells with a larger rms residual are refitted ...
constexpr double kOutlierSigmas = 2.5;  // ... without the points this many rms off the plane
// An occupied cell whose elevation lies this far above the median of its occupied neighbours'
// planes (extrapolated to its centre; 3 or more of the 8) is a spike: low vegetation or an
// object labelled ground. It is dropped and filled like an empty cell [m].
constexpr float kSpikeHeight = 0.25f;
constexpr double kConfidencePoints = 3.0;  // confidence n / (n + this) ...
constexpr double kConfidenceRms = 0.05;    // ... / (1 + (rms / this)^2) [m]

// flags_ bits.
constexpr std::uint8_t kOccupied = 1;  // holds ground points: z from its own points
constexpr std::uint8_t kPoint = 2;     // some point of the build cloud lies in the cell
constexpr std::uint8_t kRefit = 4;     // refitted without its outliers
constexpr std::uint8_t kSpike = 8;     // dropped: too high above its neighbours

// x, y, z of a CloudView held in locals (see accumulate()).
struct XyzReader {
  explicit XyzReader(const CloudView& c)
      : data(c.data()), stride(c.stride()), ox(c.xOffset()), oy(c.yOffset()), oz(c.zOffset()) {}
  bool get(std::size_t i, float* x, float* y, float* z) const {
    const std::uint8_t* p = data + i * stride;
    std::memcpy(x, p + ox, sizeof(float));
    std::memcpy(y, p + oy, sizeof(float));
    std::memcpy(z, p + oz, sizeof(float));
    return std::isfinite(*x) && std::isfinite(*y) && std::isfinite(*z);
  }
  const std::uint8_t* data;
  std::size_t stride, ox, oy, oz;
};

void checkRange(const char* name, double v, double lo, double hi) {
  if (!(v >= lo && v <= hi)) {
    std::ostringstream os;
    os << "parameter '" << name << "' = " << v << " is out of range [" << lo << ", " << hi << "]";
    throw std::invalid_argument(os.str());
  }
}

}  // namespace

void GroundSurfaceParams::validate() const {
  checkRange("cell", cell, 0.05, 100.0);
  checkRange("radius", radius, 0.0, 1000.0);
}

void GroundSurface::chooseGrid(double min_x, double min_y, double max_x, double max_y,
                               double radius, double cell) {
  const double margin = radius + 2.0 * cell;
  const double w = max_x - min_x + 2.0 * margin, h = max_y - min_y + 2.0 * margin;
  const double need = (w / cell + 2.0) * (h / cell + 2.0);
  const double most = static_cast<double>(GroundSurfaceParams::kMaxCells);
  for (double k = std::max(1.0, std::ceil(std::sqrt(need / most)));; k += 1.0) {
    cell_ = cell * k;
    const double m = radius + 2.0 * cell_;
    const double x0 = std::floor((min_x - m) / cell_) * cell_;
    const double y0 = std::floor((min_y - m) / cell_) * cell_;
    const double nx = std::floor((max_x + m - x0) / cell_) + 1.0;
    const double ny = std::floor((max_y + m - y0) / cell_) + 1.0;
    if (nx * ny <= most) {
      x0_ = static_cast<float>(x0);
      y0_ = static_cast<float>(y0);
      nx_ = static_cast<int>(nx);
      ny_ = static_cast<int>(ny);
      return;
    }
  }
}

// Sums of the ground points of each occupied cell (x, y relative to the cell centre, z to
// z_ref_), the occupied cells in the order their first point comes, and the kPoint marks.
// refit: of the cells marked kRefit only, the points within kOutlierSigmas rms of fit_.
void GroundSurface::accumulate(const CloudView& cloud, const std::vector<std::uint8_t>& labels,
                               bool refit) {
  // Locals only in the loop: the byte stores to flags would make the compiler reload members.
  const XyzReader in(cloud);
  const float inv = static_cast<float>(1.0 / cell_), cell = static_cast<float>(cell_);
  const float hi_u = static_cast<float>(nx_), hi_v = static_cast<float>(ny_);
  const float x0 = x0_, y0 = y0_;
  const double z_ref = z_ref_;
  const std::size_t nx = static_cast<std::size_t>(nx_), n = labels.size();
  const std::uint8_t* label = labels.data();
  std::uint8_t* flags = flags_.data();
  std::int32_t* slot = slot_.data();
  const Fit* fit = fit_.data();
  Accum* acc = acc_.data();
  std::int32_t* point_cell = point_cell_.data();
  for (std::size_t i = 0; i < n; ++i) {
    const bool ground = label[i] == 1;
    if (refit) {
      const std::int32_t c = point_cell[i];
      if (!ground || c < 0 || !(flags[c] & kRefit)) continue;
    } else {
      point_cell[i] = -1;
    }
    float x, y, z;
    if (!in.get(i, &x, &y, &z)) continue;
    const float fx = (x - x0) * inv, fy = (y - y0) * inv;
    if (!(fx >= 0.f && fy >= 0.f && fx < hi_u && fy < hi_v)) continue;
    // fx, fy >= 0: truncation is floor, and cheaper.
    const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
    const std::size_t g = static_cast<std::size_t>(iy) * nx + static_cast<std::size_t>(ix);
    point_cell[i] = static_cast<std::int32_t>(g);
    if (!ground) {
      flags[g] |= kPoint;
      continue;
    }
    std::int32_t s = slot[g];
    if (s < 0) {
      s = slot[g] = static_cast<std::int32_t>(occupied_.size());
      occupied_.push_back(static_cast<std::uint32_t>(g));
      acc_.push_back(Accum{0, 0, 0, 0, 0, 0, 0, 0, 0, 0});
      acc = acc_.data();
      flags[g] |= kOccupied | kPoint;
    }
    const double dx = (fx - static_cast<float>(ix) - 0.5f) * cell;
    const double dy = (fy - static_cast<float>(iy) - 0.5f) * cell;
    const double dz = z - z_ref;
    if (refit) {
      const Fit& f = fit[s];
      if (std::fabs(dz - f.z - f.gx * dx - f.gy * dy) > kOutlierSigmas * f.rms) continue;
    }
    Accum& a = acc[s];
    a.n += 1.0;
    a.sx += dx;
    a.sy += dy;
    a.sz += dz;
    a.sxx += dx * dx;
    a.sxy += dx * dy;
    a.syy += dy * dy;
    a.sxz += dx * dz;
    a.syz += dy * dz;
    a.szz += dz * dz;
  }
}

// Least squares z = z0 + g . d on the directions the points spread along (a pseudo-inverse of
// their 2x2 covariance); mean z where they do not, or where the slope is implausible.
GroundSurface::Fit GroundSurface::fitCell(const Accum& a) const {
  const double min_var = (kMinSpreadShare * cell_) * (kMinSpreadShare * cell_);
  const double mx = a.sx / a.n, my = a.sy / a.n, mz = a.sz / a.n;
  const double cxx = a.sxx / a.n - mx * mx, cxy = a.sxy / a.n - mx * my;
  const double cyy = a.syy / a.n - my * my, czz = a.szz / a.n - mz * mz;
  const double cxz = a.sxz / a.n - mx * mz, cyz = a.syz / a.n - my * mz;
  // Eigen decomposition of [[cxx, cxy], [cxy, cyy]]: l1 >= l2, e1 the direction of l1.
  const double tr = 0.5 * (cxx + cyy), diff = 0.5 * (cxx - cyy);
  const double root = std::sqrt(diff * diff + cxy * cxy);
  const double l1 = tr + root, l2 = tr - root;
  double e1x = cxx >= cyy ? 1.0 : 0.0, e1y = cxx >= cyy ? 0.0 : 1.0;
  if (cxy != 0.0) {
    const double ux = l1 - cyy, uy = cxy, len = std::sqrt(ux * ux + uy * uy);
    e1x = ux / len;
    e1y = uy / len;
  }
  double gx = 0.0, gy = 0.0, s1 = 0.0, s2 = 0.0;
  if (a.n >= 2.0 && l1 >= min_var) {
    s1 = (e1x * cxz + e1y * cyz) / l1;
    if (a.n >= 3.0 && l2 >= min_var) s2 = (-e1y * cxz + e1x * cyz) / l2;
    gx = s1 * e1x - s2 * e1y;
    gy = s1 * e1y + s2 * e1x;
  }
  if (gx * gx + gy * gy > kMaxSlope * kMaxSlope) gx = gy = s1 = s2 = 0.0;
  // Residual variance: var(z) less what the slope explains.
  const double res =
      czz - s1 * s1 * (l1 >= min_var ? l1 : 0.0) - s2 * s2 * (l2 >= min_var ? l2 : 0.0);
  return Fit{mz - gx * mx - gy * my, gx, gy, std::sqrt(std::max(0.0, res))};
}

// Marks the occupied cells that stand more than kSpikeHeight above the median of their occupied
// neighbours' planes, then turns them into empty cells (fill() fills them).
void GroundSurface::dropSpikes() {
  const float cell = static_cast<float>(cell_);
  std::size_t spikes = 0;
  for (const std::uint32_t g : occupied_) {
    const int i = static_cast<int>(g % nx_), j = static_cast<int>(g / nx_);
    float pred[8];
    int k = 0;
    for (int jj = std::max(0, j - 1); jj <= std::min(ny_ - 1, j + 1); ++jj) {
      for (int ii = std::max(0, i - 1); ii <= std::min(nx_ - 1, i + 1); ++ii) {
        const std::size_t h = static_cast<std::size_t>(jj) * nx_ + ii;
        if (h == g || occ_[h] == 0.f) continue;
        pred[k++] = z_[h] + gx_[h] * static_cast<float>(i - ii) * cell +
                    gy_[h] * static_cast<float>(j - jj) * cell;
      }
    }
    if (k < 3) continue;
    std::nth_element(pred, pred + k / 2, pred + k);
    if (z_[g] - pred[k / 2] > kSpikeHeight) {
      flags_[g] |= kSpike;
      ++spikes;
    }
  }
  if (spikes == 0) return;
  for (const std::uint32_t g : occupied_) {
    if (!(flags_[g] & kSpike)) continue;
    flags_[g] &= static_cast<std::uint8_t>(~kOccupied);
    occ_[g] = 0.f;
    centre_[g].has = -1.f;
  }
}

// Inverse-distance-weighted elevation at the centre of cell (i, j) from the planes of the
// occupied cells within the radius, each extrapolated to that centre.
bool GroundSurface::idw(int i, int j, Centre* out) const {
  const int reach = static_cast<int>(std::floor(radius_ / cell_));
  const int side = 2 * reach + 1;
  const float cell = static_cast<float>(cell_);
  // Two partial sums (even / odd ii): two add chains instead of one; dx kept as a float that
  // steps by the cell (an int-to-float conversion a term was the slow part).
  float sw0 = 0.f, sw1 = 0.f, sz0 = 0.f, sz1 = 0.f;
  const int i_lo = std::max(0, i - reach), i_hi = std::min(nx_ - 1, i + reach);
  const float* kernel = kernel_.data();
  const float *occ = occ_.data(), *zs = z_.data(), *gxs = gx_.data(), *gys = gy_.data();
  const float dx_lo = static_cast<float>(i - i_lo) * cell;
  for (int jj = std::max(0, j - reach); jj <= std::min(ny_ - 1, j + reach); ++jj) {
    // kernel entry of (ii, jj): k[ii]; grid cell: row + ii.
    const float* k = kernel + (static_cast<std::ptrdiff_t>(jj - j + reach) * side + reach - i);
    const std::size_t row = static_cast<std::size_t>(jj) * nx_;
    const float *o = occ + row, *zr = zs + row, *gxr = gxs + row, *gyr = gys + row;
    const float dy = static_cast<float>(j - jj) * cell;
    float dx = dx_lo;
    int ii = i_lo;
    for (; ii + 1 <= i_hi; ii += 2, dx -= 2.f * cell) {
      const float w0 = k[ii] * o[ii], w1 = k[ii + 1] * o[ii + 1];
      sw0 += w0;
      sw1 += w1;
      sz0 += w0 * (zr[ii] + gxr[ii] * dx + gyr[ii] * dy);
      sz1 += w1 * (zr[ii + 1] + gxr[ii + 1] * (dx - cell) + gyr[ii + 1] * dy);
    }
    if (ii <= i_hi) {
      const float w = k[ii] * o[ii];
      sw0 += w;
      sz0 += w * (zr[ii] + gxr[ii] * dx + gyr[ii] * dy);
    }
  }
  const float w = sw0 + sw1, z = sz0 + sz1;
  *out = w > 0.f ? Centre{z / w, 1.f} : Centre{0.f, 0.f};
  return w > 0.f;
}

// Fills the empty cells that a point of the build cloud may blend (its cell and the 8 around).
void GroundSurface::fill() {
  const int reach = static_cast<int>(std::floor(radius_ / cell_));
  const int side = 2 * reach + 1;
  kernel_.assign(static_cast<std::size_t>(side) * side, 0.f);
  for (int dj = -reach; dj <= reach; ++dj) {
    for (int di = -reach; di <= reach; ++di) {
      const double d2 = (di * di + dj * dj) * cell_ * cell_;
      if (d2 > 0.0 && d2 <= radius_ * radius_) {
        kernel_[static_cast<std::size_t>(dj + reach) * side + di + reach] =
            static_cast<float>(1.0 / d2);
      }
    }
  }
  for (int j = 0; j < ny_; ++j) {
    for (int i = 0; i < nx_; ++i) {
      const std::size_t g = static_cast<std::size_t>(j) * nx_ + i;
      if (flags_[g] & kOccupied) continue;
      bool wanted = false;
      for (int jj = std::max(0, j - 1); jj <= std::min(ny_ - 1, j + 1); ++jj) {
        for (int ii = std::max(0, i - 1); ii <= std::min(nx_ - 1, i + 1); ++ii) {
          wanted |= (flags_[static_cast<std::size_t>(jj) * nx_ + ii] & kPoint) != 0;
        }
      }
      if (!wanted) continue;
      idw(i, j, &centre_[g]);
    }
  }
}

void GroundSurface::build(const CloudView& cloud, const std::vector<std::uint8_t>& labels,
                          const GroundSurfaceParams& params) {
  params.validate();
  const std::size_t n = cloud.size();
  if (labels.size() != n) {
    throw std::invalid_argument("GroundSurface::build: " + std::to_string(labels.size()) +
                                " labels for " + std::to_string(n) + " points");
  }
  radius_ = params.radius;
  cells_.clear();
  occupied_.clear();
  acc_.clear();
  nx_ = ny_ = 0;
  float min_x = std::numeric_limits<float>::infinity(), min_y = min_x;
  float max_x = -min_x, max_y = -min_x;
  bool any = false;
  for (std::size_t i = 0; i < n; ++i) {
    float x, y, z;
    if (labels[i] != 1 || !cloud.get(i, &x, &y, &z)) continue;
    if (!any) z_ref_ = z;
    any = true;
    min_x = std::min(min_x, x);
    max_x = std::max(max_x, x);
    min_y = std::min(min_y, y);
    max_y = std::max(max_y, y);
  }
  if (!any) return;
  chooseGrid(min_x, min_y, max_x, max_y, params.radius, params.cell);
  const std::size_t cells = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  flags_.assign(cells, 0);
  slot_.assign(cells, -1);
  point_cell_.resize(n);
  // Fit, refit the noisy cells without their outliers.
  accumulate(cloud, labels, false);
  const std::size_t occ = occupied_.size();
  fit_.resize(occ);
  count_.resize(occ);
  bool refit = false;
  for (std::size_t s = 0; s < occ; ++s) {
    count_[s] = static_cast<std::uint32_t>(acc_[s].n);
    fit_[s] = fitCell(acc_[s]);
    if (fit_[s].rms > kRefitRms) {
      flags_[occupied_[s]] |= kRefit;
      acc_[s] = Accum{0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
      refit = true;
    }
  }
  if (refit) {
    accumulate(cloud, labels, true);
    for (std::size_t s = 0; s < occ; ++s) {
      if ((flags_[occupied_[s]] & kRefit) && acc_[s].n > 0.0) fit_[s] = fitCell(acc_[s]);
    }
  }
  occ_.assign(cells, 0.f);
  z_.assign(cells, 0.f);
  gx_.assign(cells, 0.f);
  gy_.assign(cells, 0.f);
  centre_.assign(cells, Centre{0.f, -1.f});
  for (std::size_t s = 0; s < occ; ++s) {
    const std::uint32_t g = occupied_[s];
    occ_[g] = 1.f;
    z_[g] = static_cast<float>(fit_[s].z + z_ref_);
    gx_[g] = static_cast<float>(fit_[s].gx);
    gy_[g] = static_cast<float>(fit_[s].gy);
    centre_[g] = Centre{z_[g], 1.f};
  }
  dropSpikes();
  // The cells in grid order (occupied_ is in the order of the points).
  order_.resize(occ);
  for (std::size_t s = 0; s < occ; ++s) order_[s] = static_cast<std::uint32_t>(s);
  std::sort(order_.begin(), order_.end(),
            [&](std::uint32_t a, std::uint32_t b) { return occupied_[a] < occupied_[b]; });
  for (std::size_t k = 0; k < occ; ++k) {
    const std::uint32_t s = order_[k], g = occupied_[s];
    if (flags_[g] & kSpike) continue;
    const double pts = count_[s], q = fit_[s].rms / kConfidenceRms;
    cells_.push_back(
        SurfaceCell{static_cast<float>(x0_ + ((g % nx_) + 0.5) * cell_),
                    static_cast<float>(y0_ + ((g / nx_) + 0.5) * cell_), z_[g], count_[s],
                    static_cast<float>(pts / (pts + kConfidencePoints) / (1.0 + q * q))});
  }
  fill();
}

// elevation() anywhere: cells the build cloud did not need are filled here, on the fly.
float GroundSurface::slowElevation(float x, float y) const {
  if (nx_ == 0 || !std::isfinite(x) || !std::isfinite(y)) return kNaN;
  const float inv = static_cast<float>(1.0 / cell_);
  const float u = (x - x0_) * inv - 0.5f, v = (y - y0_) * inv - 0.5f;
  if (!(u >= -1.f && v >= -1.f && u < nx_ && v < ny_)) return kNaN;
  const int i0 = static_cast<int>(std::floor(u)), j0 = static_cast<int>(std::floor(v));
  const float tx = u - i0, ty = v - j0;
  float sw = 0.f, sz = 0.f;
  for (int dj = 0; dj < 2; ++dj) {
    for (int di = 0; di < 2; ++di) {
      const int i = i0 + di, j = j0 + dj;
      const float w = (di ? tx : 1.f - tx) * (dj ? ty : 1.f - ty);
      if (i < 0 || i >= nx_ || j < 0 || j >= ny_ || !(w > 0.f)) continue;
      Centre p = centre_[static_cast<std::size_t>(j) * nx_ + i];
      if (p.has < 0.f) idw(i, j, &p);
      if (p.has == 0.f) continue;
      sw += w;
      sz += w * p.z;
    }
  }
  return sw > 1e-6f ? sz / sw : kNaN;
}

float GroundSurface::elevation(float x, float y) const { return slowElevation(x, y); }

float GroundSurface::heightAbove(float x, float y, float z) const {
  if (!std::isfinite(z)) return kNaN;
  return z - elevation(x, y);
}

void GroundSurface::heights(const CloudView& cloud, std::vector<float>* out) const {
  const std::size_t n = cloud.size();
  out->resize(n);
  float* h = out->data();
  const XyzReader in(cloud);
  const float inv = static_cast<float>(1.0 / cell_);
  const float hi_u = static_cast<float>(nx_ - 1), hi_v = static_cast<float>(ny_ - 1);
  const float x0 = x0_, y0 = y0_;
  const std::size_t nx = static_cast<std::size_t>(nx_);
  const Centre* centre = centre_.data();
  for (std::size_t i = 0; i < n; ++i) {
    float x, y, z;
    if (!in.get(i, &x, &y, &z)) {
      h[i] = kNaN;
      continue;
    }
    const float u = (x - x0) * inv - 0.5f, v = (y - y0) * inv - 0.5f;
    if (!(u >= 0.f && v >= 0.f && u < hi_u && v < hi_v)) {
      h[i] = z - slowElevation(x, y);
      continue;
    }
    // Inside the grid: the four cells around (x, y), each computed by build().
    const int i0 = static_cast<int>(u), j0 = static_cast<int>(v);
    const float tx = u - static_cast<float>(i0), ty = v - static_cast<float>(j0);
    const Centre* p0 = centre + static_cast<std::size_t>(j0) * nx + static_cast<std::size_t>(i0);
    const Centre a = p0[0], b = p0[1], c = p0[nx], d = p0[nx + 1];
    if (std::min(std::min(a.has, b.has), std::min(c.has, d.has)) < 0.f) {
      h[i] = z - slowElevation(x, y);
      continue;
    }
    const float wa = (1.f - tx) * (1.f - ty), wb = tx * (1.f - ty);
    const float wc = (1.f - tx) * ty, wd = tx * ty;
    // An undefined cell holds z = 0 and weight 0.
    const float sz = wa * a.z + wb * b.z + wc * c.z + wd * d.z;
    if (a.has + b.has + c.has + d.has == 4.f) {
      h[i] = z - sz;  // the common case: no renormalisation (no division)
      continue;
    }
    const float sw = wa * a.has + wb * b.has + wc * c.has + wd * d.has;
    h[i] = sw > 1e-6f ? z - sz / sw : kNaN;
  }
}

}  // namespace ground_filter
