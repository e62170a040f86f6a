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

#include "common/threads_timing.h"
#include "hag/surface_points.h"
#include "simd/avx2_common.h"
#include "simd/simd.h"

namespace ground_filter {

constexpr std::size_t GroundSurfaceParams::kMaxCells;

namespace {

using hag::bilinear;
using hag::kNaN;
using hag::Lookup;
using hag::ScalarRun;
using hag::XyzReader;
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
// An occupied cell is a spike too where it stands more than this above the median of the
// occupied cells within kPatchReach cells (extrapolated likewise): a patch of vegetation or of
// an object labelled ground, a few cells wide. Larger than kSpikeHeight: planes extrapolated
// over two cells carry more of the terrain's curvature, and a step up to this stays. The
// middle of the range 0.30-0.425 m where both generated vegetation scenes keep their gain
// (docs/height_above_ground.md, "Plateaus") [m].
constexpr float kPatchHeight = 0.35f;
constexpr int kPatchReach = 2;   // cells: the wider window is 5 x 5
constexpr int kPatchLeast = 12;  // occupied cells of its 24 that the wider test needs
// A ground-level scanner leaves occlusion shadows behind bushes, trunks and cars: a cell
// among them has too few occupied cells around it for the tests above (fewer than kPatchLeast
// of its 24), so it is judged against the occupied cells kShadowInner to kShadowReach cells
// away (kShadowLeast or more; their elevations), the terrain beyond the shadow: more than
// kShadowHeight above their median, it is a spike. Larger than kPatchHeight: the terrain may
// rise or fall over 3-5 cells. Airborne scans have no such shadows (their gaps are buildings
// and steep slopes, where the test hurt): ground-level scans only
// (GroundSurfaceParams::ground_level). 1.0 m: inside 0.75-2.0 m, where the generated trail and
// off-road scenes keep their gain and no dev group loses (docs/height_above_ground.md,
// "Plateaus") [m].
constexpr float kShadowHeight = 1.0f;
constexpr int kShadowInner = 3;            // cells: the ring starts outside the 5 x 5 window ...
constexpr int kShadowReach = 5;            // ... and ends at the 11 x 11 window's edge
constexpr int kShadowLeast = 6;            // occupied cells of the ring's 96 that the test needs
constexpr double kConfidencePoints = 3.0;  // confidence n / (n + this) ...
constexpr double kConfidenceRms = 0.05;    // ... / (1 + (rms / this)^2) [m]

// Points a thread of heights() takes at least: a small scan runs on one (a team's start costs a
// few microseconds).
constexpr std::size_t kPointsEach = 16384;

// flags_ bits (per occupied cell).
constexpr std::uint8_t kRefit = 1;  // refitted without its outliers
constexpr std::uint8_t kSpike = 2;  // dropped: too high above its neighbours

// Whether the AVX2 passes run: the GF_SIMD level allows them and the CPU has them.
inline bool avx2Paths() {
#if GF_HAVE_AVX2_PATHS
  return simd::allows(simd::Level::kAvx2) && simd::avx2::cpuHasAvx2();
#else
  return false;
#endif
}

// Heights of points [begin, end) of `in` into h.
void heightsScalar(const XyzReader& in, const Lookup& at, std::size_t begin, std::size_t end,
                   float* h) {
  const Lookup a = at;  // locals: the stores to h would make the compiler reload them
  for (std::size_t i = begin; i < end; ++i) {
    float x, y, z;
    const bool ok = in.get(i, &x, &y, &z);
    const float u = (x - a.x0) * a.inv - 0.5f, v = (y - a.y0) * a.inv - 0.5f;
    // Outside the grid: beyond the radius of every occupied cell (the grid's margin).
    if (!ok || !(u >= 0.f && v >= 0.f && u < a.hi_u && v < a.hi_v)) {
      h[i] = kNaN;
      continue;
    }
    const int i0 = static_cast<int>(u), j0 = static_cast<int>(v);
    const float* p = a.centre + static_cast<std::size_t>(j0) * a.nx + static_cast<std::size_t>(i0);
    h[i] = z - bilinear(p[0], p[1], p[a.nx], p[a.nx + 1], u - static_cast<float>(i0),
                        v - static_cast<float>(j0));
  }
}

// Whether z stands more than `height` above the median of pred[0, k), with k >= least.
bool aboveMedian(float z, float* pred, int k, int least, float height) {
  // Most cells stand no higher than `height` above their lowest neighbour: no median needed.
  if (k < least || z - *std::min_element(pred, pred + k) <= height) return false;
  std::nth_element(pred, pred + k / 2, pred + k);
  return z - pred[k / 2] > height;
}

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
  checkRange("threads", threads, 0.0, 256.0);
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

// The finite ground points into px_, py_, pz_ (in cloud order) and their x/y bounds: the one
// pass over the whole cloud; everything after it reads these dense arrays.
bool GroundSurface::gatherGround(const CloudView& cloud, const std::vector<std::uint8_t>& labels,
                                 float* bounds) {
  const std::size_t n = labels.size();
  if (px_.size() < n) {
    px_.resize(n);
    py_.resize(n);
    pz_.resize(n);
    pslot_.resize(n);
  }
  const XyzReader in(cloud);
  const std::uint8_t* label = labels.data();
  float *px = px_.data(), *py = py_.data(), *pz = pz_.data();
  const float inf = std::numeric_limits<float>::infinity();
  bounds[0] = bounds[1] = inf;
  bounds[2] = bounds[3] = -inf;
  std::size_t k = 0, i = 0;
#if GF_HAVE_AVX2_PATHS
  if (avx2Paths()) i = hag::gatherAvx2(in, label, n, px, py, pz, &k, bounds);
#endif
  float min_x = bounds[0], min_y = bounds[1], max_x = bounds[2], max_y = bounds[3];
  for (; i < n; ++i) {
    float x, y, z;
    if (label[i] != 1 || !in.get(i, &x, &y, &z)) continue;
    px[k] = x;
    py[k] = y;
    pz[k] = z;
    ++k;
    min_x = std::min(min_x, x);
    max_x = std::max(max_x, x);
    min_y = std::min(min_y, y);
    max_y = std::max(max_y, y);
  }
  ground_ = k;
  bounds[0] = min_x;
  bounds[1] = min_y;
  bounds[2] = max_x;
  bounds[3] = max_y;
  return k > 0;
}

// Each ground point's grid cell (into pslot_, for accumulate()) and its x, y relative to the
// cell centre (over px_, py_): a loop without branches or table lookups, which the compiler
// vectorises.
void GroundSurface::cellOffsets() {
  const float inv = static_cast<float>(1.0 / cell_), cell = static_cast<float>(cell_);
  const float x0 = x0_, y0 = y0_, nxf = static_cast<float>(nx_);
  const std::size_t n = ground_;
  float* __restrict px = px_.data();
  float* __restrict py = py_.data();
  std::int32_t* __restrict g = pslot_.data();
  for (std::size_t i = 0; i < n; ++i) {
    // Every ground point lies inside the grid (it spans their bounds plus a margin), and
    // fx, fy >= 0: truncation is floor. iy * nx + ix < kMaxCells < 2^24: exact in a float.
    const float fx = (px[i] - x0) * inv, fy = (py[i] - y0) * inv;
    const float ix = static_cast<float>(static_cast<int>(fx));
    const float iy = static_cast<float>(static_cast<int>(fy));
    px[i] = (fx - ix - 0.5f) * cell;
    py[i] = (fy - iy - 0.5f) * cell;
    g[i] = static_cast<std::int32_t>(iy * nxf + ix);
  }
}

// Sums of the ground points of each occupied cell (x, y relative to the cell centre, z to
// z_ref_) and the occupied cells in the order their first point comes; the runs of consecutive
// points in one cell (run_start_, run_slot_). refit: of the cells marked kRefit only, the points
// within kOutlierSigmas rms of fit_, read run by run (the other runs' points are not touched):
// the same points in the same order as a pass over all of them.
template <class Run>
inline __attribute__((always_inline)) void GroundSurface::accumulateWith(bool refit) {
  // Locals only in the loops: the stores would make the compiler reload members.
  const double z_ref = z_ref_;
  const std::size_t n = ground_;
  const float *px = px_.data(), *py = py_.data(), *pz = pz_.data();
  Accum* acc = acc_.data();
  // Consecutive points mostly share a cell: their sums run in registers (`run`) and go to the
  // cell's Accum when the cell changes, instead of a load and store of it for every point.
  Run run;
  run.reset();
  std::int32_t cur = -1;
  if (!refit) {
    const std::int32_t* cell = pslot_.data();
    std::int32_t* slot = slot_.data();
    run_start_.clear();
    run_slot_.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const std::int32_t g = cell[i];
      std::int32_t s = slot[g];
      if (s < 0) {
        s = slot[g] = static_cast<std::int32_t>(occupied_.size());
        occupied_.push_back(static_cast<std::uint32_t>(g));
        acc_.push_back(Accum{0, 0, 0, 0, 0, 0, 0, 0, 0, 0});
        acc = acc_.data();
      }
      if (s != cur) {
        if (cur >= 0) run.addTo(&acc[cur].n);
        cur = s;
        run.reset();
        run_start_.push_back(static_cast<std::uint32_t>(i));
        run_slot_.push_back(s);
      }
      run.add(px[i], py[i], pz[i] - z_ref);
    }
  } else {
    const std::uint8_t* flags = flags_.data();
    const Fit* fit = fit_.data();
    const std::uint32_t* start = run_start_.data();
    const std::int32_t* run_slot = run_slot_.data();
    const std::size_t runs = run_start_.size();
    for (std::size_t r = 0; r < runs; ++r) {
      const std::int32_t s = run_slot[r];
      if (!(flags[s] & kRefit)) continue;
      const Fit f = fit[s];
      const std::size_t end = r + 1 < runs ? start[r + 1] : n;
      for (std::size_t i = start[r]; i < end; ++i) {
        const double dx = px[i], dy = py[i], dz = pz[i] - z_ref;
        if (std::fabs(dz - f.z - f.gx * dx - f.gy * dy) > kOutlierSigmas * f.rms) continue;
        if (s != cur) {
          if (cur >= 0) run.addTo(&acc[cur].n);
          cur = s;
          run.reset();
        }
        run.add(dx, dy, dz);
      }
    }
  }
  if (cur >= 0) run.addTo(&acc[cur].n);
}

// accumulateWith() with the AVX2 registers where the CPU and GF_SIMD allow them.
void GroundSurface::accumulate(bool refit) {
  static_assert(sizeof(Accum) == 10 * sizeof(double), "Accum: ten doubles, no padding");
#if GF_HAVE_AVX2_PATHS
  if (avx2Paths()) {
    accumulateAvx2(refit);
    return;
  }
#endif
  accumulateWith<ScalarRun>(refit);
}

#if GF_HAVE_AVX2_PATHS
GF_TARGET_AVX2_PATHS void GroundSurface::accumulateAvx2(bool refit) {
  accumulateWith<hag::Avx2Run>(refit);
}
#else
void GroundSurface::accumulateAvx2(bool refit) { accumulateWith<ScalarRun>(refit); }
#endif

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

// Marks the spikes: occupied cells more than kSpikeHeight above the median of their 8
// neighbours (3 or more occupied), or more than kPatchHeight above the median of the 24 within
// kPatchReach cells (half of them or more occupied: a sparse window, as an airborne scan's on a
// steep slope, extrapolates cells without a fitted slope too far). A patch of low vegetation or
// an object labelled ground spans several cells, so its nearest neighbours stand as high as it
// does; two cells out the terrain around it is the majority. In a ground-level scan a cell
// that the wider window cannot judge gets the shadow test (shadowSpike()).
// fill() treats them as empty cells.
void GroundSurface::dropSpikes() {
  const float cell = static_cast<float>(cell_);
  const std::size_t occ = occupied_.size();
  if (ground_level_) blockLows();
  // Most cells stand no higher above their lowest neighbours than the tests allow: found from
  // every grid cell's plane in three dense arrays (z +inf, no slope where the cell is empty, so
  // no branch on which neighbours are occupied), the medians are left out. The arrays are the
  // fill's (wsum_, centre_: fill() sets them anew) and gy_grid_.
  const std::size_t cells = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  wsum_.assign(cells, std::numeric_limits<float>::infinity());
  centre_.assign(cells, 0.f);
  gy_grid_.assign(cells, 0.f);
  float *pz = wsum_.data(), *pgx = centre_.data(), *pgy = gy_grid_.data();
  for (std::size_t s = 0; s < occ; ++s) {
    const std::uint32_t g = occupied_[s];
    pz[g] = z_[s];
    pgx[g] = gx_[s];
    pgy[g] = gy_[s];
  }
  for (std::size_t s = 0; s < occ; ++s) {
    const std::uint32_t g = occupied_[s];
    const int j = static_cast<int>(g / nx_), i = static_cast<int>(g) - j * nx_;
    bool judged = false, spike = false;
    int ka = 0;
    if (i >= kPatchReach && j >= kPatchReach && i < nx_ - kPatchReach && j < ny_ - kPatchReach) {
      // The lowest of the neighbours' planes at this centre (the same values as medianSpike()), and
      // the occupied cells of the window.
      float low_near = std::numeric_limits<float>::infinity(), low_all = low_near;
      int occupied = 0;
      for (int dj = -kPatchReach; dj <= kPatchReach; ++dj) {
        const std::size_t row = static_cast<std::size_t>(j + dj) * nx_ + i;
        const float *rz = pz + row, *rgx = pgx + row, *rgy = pgy + row;
        for (int di = -kPatchReach; di <= kPatchReach; ++di) {
          if (di == 0 && dj == 0) continue;
          const float p = rz[di] + rgx[di] * static_cast<float>(-di) * cell +
                          rgy[di] * static_cast<float>(-dj) * cell;
          occupied += rz[di] != std::numeric_limits<float>::infinity();
          low_all = std::min(low_all, p);
          if (di >= -1 && di <= 1 && dj >= -1 && dj <= 1) low_near = std::min(low_near, p);
        }
      }
      const float z = z_[s];
      judged = z - low_near <= kSpikeHeight && z - low_all <= kPatchHeight;  // no median needed
      ka = occupied;
    }
    if (!judged) spike = medianSpike(s, i, j, &ka);
    if (!spike && ground_level_ && ka < kPatchLeast) spike = shadowSpike(s, i, j);
    if (spike) flags_[s] |= kSpike;
  }
}

// The tests of dropSpikes() with the medians, for occupied cell s at grid (i, j); *ka gets the
// occupied cells of its window.
bool GroundSurface::medianSpike(std::size_t s, int i, int j, int* ka_out) const {
  const float cell = static_cast<float>(cell_);
  // The neighbours' planes at this centre: all within kPatchReach, and the 8 nearest.
  float all[(2 * kPatchReach + 1) * (2 * kPatchReach + 1)], near[8];
  int ka = 0, kn = 0;
  for (int dj = std::max(-kPatchReach, -j); dj <= std::min(kPatchReach, ny_ - 1 - j); ++dj) {
    const std::int32_t* row = slot_.data() + static_cast<std::size_t>(j + dj) * nx_ + i;
    for (int di = std::max(-kPatchReach, -i); di <= std::min(kPatchReach, nx_ - 1 - i); ++di) {
      const std::int32_t t = row[di];
      if (t < 0 || (di == 0 && dj == 0)) continue;
      const float p =
          z_[t] + gx_[t] * static_cast<float>(-di) * cell + gy_[t] * static_cast<float>(-dj) * cell;
      all[ka++] = p;
      if (di >= -1 && di <= 1 && dj >= -1 && dj <= 1) near[kn++] = p;
    }
  }
  *ka_out = ka;
  return aboveMedian(z_[s], near, kn, 3, kSpikeHeight) ||
         aboveMedian(z_[s], all, ka, kPatchLeast, kPatchHeight);
}

// The shadow test of dropSpikes() for occupied cell s at grid (i, j): whether it stands more
// than kShadowHeight above the median elevation of the occupied cells kShadowInner to
// kShadowReach cells away. Their elevations at their own centres, not their planes
// extrapolated: a sparse cell's slope carried 3-5 cells adds as much error as it removes
// (docs/height_above_ground.md, "Plateaus"), and without it the blocks' lowest elevations
// bound the ring from below. Counted rather than sorted: the median lies that far below
// exactly when more than half of them do.
bool GroundSurface::shadowSpike(std::size_t s, int i, int j) const {
  const float z = z_[s];
  // No cell of the 4 x 4-cell blocks around the ring lies that far below: none of the ring
  // does (most cells stop here).
  const int bi0 = std::max(0, i - kShadowReach) / kBlock, bi1 = (i + kShadowReach) / kBlock;
  const int bj0 = std::max(0, j - kShadowReach) / kBlock, bj1 = (j + kShadowReach) / kBlock;
  float low = std::numeric_limits<float>::infinity();
  for (int bj = bj0; bj <= std::min(bj1, bny_ - 1); ++bj) {
    for (int bi = bi0; bi <= std::min(bi1, bnx_ - 1); ++bi) {
      low = std::min(low, block_low_[static_cast<std::size_t>(bj) * bnx_ + bi]);
    }
  }
  if (!(z - low > kShadowHeight)) return false;
  int ring = 0, below = 0;
  for (int dj = std::max(-kShadowReach, -j); dj <= std::min(kShadowReach, ny_ - 1 - j); ++dj) {
    const std::int32_t* row = slot_.data() + static_cast<std::size_t>(j + dj) * nx_ + i;
    const bool inner_row = dj > -kShadowInner && dj < kShadowInner;
    for (int di = std::max(-kShadowReach, -i); di <= std::min(kShadowReach, nx_ - 1 - i); ++di) {
      const std::int32_t t = row[di];
      if (t < 0 || (inner_row && di > -kShadowInner && di < kShadowInner)) continue;
      ++ring;
      below += z - z_[t] > kShadowHeight;
    }
  }
  return ring >= kShadowLeast && 2 * below > ring;
}

// The lowest elevation of the occupied cells in each kBlock x kBlock block of the grid
// (shadowSpike()'s first look).
void GroundSurface::blockLows() {
  bnx_ = (nx_ + kBlock - 1) / kBlock;
  bny_ = (ny_ + kBlock - 1) / kBlock;
  block_low_.assign(static_cast<std::size_t>(bnx_) * bny_, std::numeric_limits<float>::infinity());
  for (std::size_t s = 0; s < occupied_.size(); ++s) {
    const std::uint32_t g = occupied_[s];
    const int j = static_cast<int>(g / nx_), i = static_cast<int>(g) - j * nx_;
    float& low = block_low_[static_cast<std::size_t>(j / kBlock) * bnx_ + i / kBlock];
    low = std::min(low, z_[s]);
  }
}

namespace {

// What fill()'s scatter reads, in locals.
template <class FitT>
struct ScatterOf {
  const std::uint32_t* occupied;  // grid cell of each occupied cell
  const std::uint8_t* flags;      // kSpike: not scattered
  const FitT* fit;                // plane height relative to z_ref at the centre
  const float *gx, *gy;           // slopes
  const float* kernel;            // (2 reach + 1)^2 weights 1 / d^2, 0 beyond the radius
  std::size_t occ;
  int nx, ny, reach;
  float cell;
};

// Each occupied cell (not a spike) adds its weights and its plane, extrapolated, to the cells
// within reach: ws and zs of a few dense row spans. Inlined into two builds (plain and AVX2), so
// the compiler vectorises the spans eight wide where it may; element by element the same
// operations, hence the same sums.
template <class Sc>
inline __attribute__((always_inline)) void scatterSpans(const Sc& a, float* __restrict ws,
                                                        float* __restrict zs) {
  const int reach = a.reach, side = 2 * reach + 1, nx = a.nx, ny = a.ny;
  for (std::size_t s = 0; s < a.occ; ++s) {
    if (a.flags[s] & kSpike) continue;
    const std::uint32_t g = a.occupied[s];
    const int i = static_cast<int>(g % static_cast<std::uint32_t>(nx));
    const int j = static_cast<int>(g / static_cast<std::uint32_t>(nx));
    const float z = static_cast<float>(a.fit[s].z), gxc = a.gx[s] * a.cell, gyc = a.gy[s] * a.cell;
    const int di_lo = std::max(-reach, -i), di_hi = std::min(reach, nx - 1 - i);
    for (int dj = std::max(-reach, -j); dj <= std::min(reach, ny - 1 - j); ++dj) {
      const float* __restrict k = a.kernel + static_cast<std::size_t>(dj + reach) * side + reach;
      const std::size_t row = static_cast<std::size_t>(j + dj) * nx + i;
      float* __restrict w = ws + row;
      float* __restrict zr = zs + row;
      const float base = z + gyc * static_cast<float>(dj);
      for (int di = di_lo; di <= di_hi; ++di) {
        w[di] += k[di];
        zr[di] += k[di] * (base + gxc * static_cast<float>(di));
      }
    }
  }
}

template <class Sc>
void scatterPlanes(const Sc& a, float* ws, float* zs) {
  scatterSpans(a, ws, zs);
}

#if GF_HAVE_AVX2_PATHS
template <class Sc>
GF_TARGET_AVX2_PATHS void scatterPlanesAvx2(const Sc& a, float* ws, float* zs) {
  scatterSpans(a, ws, zs);
}
#endif

}  // namespace

// Every cell's elevation at its centre: an occupied cell's own plane; any other cell the
// inverse-distance-weighted average of the planes of the occupied cells within the radius, each
// extrapolated to its centre, NaN where there are none. Each occupied cell adds its plane to the
// cells within the radius (a few dense row spans instead of a search around each empty cell);
// the cells_ list comes out in grid order on the way.
void GroundSurface::fill() {
  const int reach = static_cast<int>(std::floor(radius_ / cell_));
  const int side = 2 * reach + 1;
  const float cell = static_cast<float>(cell_);
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
  const std::size_t cells = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  wsum_.assign(cells, 0.f);
  centre_.assign(cells, 0.f);  // first the weighted sums of z - z_ref_
  float* __restrict ws = wsum_.data();
  float* __restrict zs = centre_.data();
  if (reach > 0) {
    const ScatterOf<Fit> sc{
        occupied_.data(), flags_.data(), fit_.data(), gx_.data(), gy_.data(), kernel_.data(),
        occupied_.size(), nx_,           ny_,         reach,      cell};
#if GF_HAVE_AVX2_PATHS
    if (avx2Paths()) {
      scatterPlanesAvx2(sc, ws, zs);
    } else {
      scatterPlanes(sc, ws, zs);
    }
#else
    scatterPlanes(sc, ws, zs);
#endif
  }
  const float z_ref = static_cast<float>(z_ref_);
  for (std::size_t g = 0; g < cells; ++g) {
    const std::int32_t s = slot_[g];
    if (s >= 0 && !(flags_[s] & kSpike)) {
      zs[g] = z_[s];
      const double pts = count_[s], q = fit_[s].rms / kConfidenceRms;
      cells_.push_back(
          SurfaceCell{static_cast<float>(x0_ + ((g % nx_) + 0.5) * cell_),
                      static_cast<float>(y0_ + ((g / nx_) + 0.5) * cell_), z_[s], count_[s],
                      static_cast<float>(pts / (pts + kConfidencePoints) / (1.0 + q * q))});
      continue;
    }
    zs[g] = ws[g] > 0.f ? z_ref + zs[g] / ws[g] : kNaN;
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
  ground_level_ = params.ground_level;
  threads_ = resolveThreads(params.threads);
  cells_.clear();
  occupied_.clear();
  acc_.clear();
  nx_ = ny_ = 0;
  float b[4];
  if (!gatherGround(cloud, labels, b)) return;
  z_ref_ = pz_[0];
  chooseGrid(b[0], b[1], b[2], b[3], params.radius, params.cell);
  const std::size_t cells = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  slot_.assign(cells, -1);
  // Fit, refit the noisy cells without their outliers.
  cellOffsets();
  accumulate(false);
  const std::size_t occ = occupied_.size();
  fit_.resize(occ);
  count_.resize(occ);
  flags_.assign(occ, 0);
  bool refit = false;
  for (std::size_t s = 0; s < occ; ++s) {
    count_[s] = static_cast<std::uint32_t>(acc_[s].n);
    fit_[s] = fitCell(acc_[s]);
    if (fit_[s].rms > kRefitRms) {
      flags_[s] = kRefit;
      acc_[s] = Accum{0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
      refit = true;
    }
  }
  if (refit) {
    accumulate(true);
    for (std::size_t s = 0; s < occ; ++s) {
      if ((flags_[s] & kRefit) && acc_[s].n > 0.0) fit_[s] = fitCell(acc_[s]);
    }
  }
  z_.resize(occ);
  gx_.resize(occ);
  gy_.resize(occ);
  for (std::size_t s = 0; s < occ; ++s) {
    z_[s] = static_cast<float>(fit_[s].z + z_ref_);
    gx_[s] = static_cast<float>(fit_[s].gx);
    gy_[s] = static_cast<float>(fit_[s].gy);
  }
  dropSpikes();
  fill();
}

float GroundSurface::elevation(float x, float y) const {
  if (nx_ == 0) return kNaN;
  const float inv = static_cast<float>(1.0 / cell_);
  const float u = (x - x0_) * inv - 0.5f, v = (y - y0_) * inv - 0.5f;
  // Outside: beyond the radius of every occupied cell (the grid's margin); NaN x, y fail too.
  if (!(u >= 0.f && v >= 0.f && u < static_cast<float>(nx_ - 1) &&
        v < static_cast<float>(ny_ - 1))) {
    return kNaN;
  }
  const int i0 = static_cast<int>(u), j0 = static_cast<int>(v);
  const float* p = centre_.data() + static_cast<std::size_t>(j0) * nx_ + i0;
  return bilinear(p[0], p[1], p[nx_], p[nx_ + 1], u - static_cast<float>(i0),
                  v - static_cast<float>(j0));
}

float GroundSurface::heightAbove(float x, float y, float z) const {
  if (!std::isfinite(z)) return kNaN;
  return z - elevation(x, y);
}

void GroundSurface::heights(const CloudView& cloud, std::vector<float>* out) const {
  const std::size_t n = cloud.size();
  out->resize(n);
  float* h = out->data();
  if (nx_ == 0) {
    std::fill(h, h + n, kNaN);
    return;
  }
  const XyzReader in(cloud);
  const Lookup at{centre_.data(),
                  static_cast<std::size_t>(nx_),
                  x0_,
                  y0_,
                  static_cast<float>(1.0 / cell_),
                  static_cast<float>(nx_ - 1),
                  static_cast<float>(ny_ - 1)};
  const bool avx2 = avx2Paths();  // once for the whole team
  // Each point's height reads the surface only: the points split over threads in any way (in
  // blocks of eight, as the AVX2 path takes them).
  const int team = static_cast<int>(std::min(std::max<std::size_t>(1, n / kPointsEach),
                                             static_cast<std::size_t>(std::max(1, threads_))));
  const std::size_t blocks = (n + 7) / 8;
#pragma omp parallel num_threads(team) if (team > 1)
  {
    std::size_t t = 0, nt = 1;
#ifdef _OPENMP
    t = static_cast<std::size_t>(omp_get_thread_num());
    nt = static_cast<std::size_t>(omp_get_num_threads());
#endif
    const std::size_t b = std::min(n, blocks * t / nt * 8),
                      e = std::min(n, blocks * (t + 1) / nt * 8);
    std::size_t i = b;
#if GF_HAVE_AVX2_PATHS
    if (avx2 && e > b) {
      XyzReader from_b = in;
      from_b.data += b * in.stride;
      i = b + hag::heightsAvx2(from_b, at, e - b, h + b);
    }
#else
    (void)avx2;
#endif
    heightsScalar(in, at, i, e, h);
  }
}

}  // namespace ground_filter
