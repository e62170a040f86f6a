#include "ground_filter/voxel_ground_filter.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "ground_filter/param_parse.h"
#include "ground_filter/plane_fit.h"

namespace ground_filter {

// ------------------------------------------------------------------------------------ impl

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

int bitsFor(std::uint64_t max_value) {
  int bits = 1;
  while ((max_value >> bits) != 0) ++bits;
  return bits;
}

constexpr int kMaxAxisBits = 21;   // 3 * 21 bits fit one 64-bit key
constexpr int kMaxDigitBits = 15;  // radix digits: at most 32 k buckets (the histograms fit L2)
// A ground seed needs this many empty voxels above it in its column: the foot of a wall, a car
// side or a fence has occupied voxels right above it, the ground does not.
constexpr std::uint32_t kSeedClearanceVoxels = 3;
// Weight of the prior slope in a cell fit, in points at a cell edge's distance: keeps a cell whose
// seeds are one scan line (collinear) from tilting around it.
constexpr double kSlopePriorWeight = 1.0;

// Below this many points a parallel region costs more than it saves (measured: a KITTI frame
// classifies in 0.8 ms on one thread, 5 ms with two on a loaded 2-core machine).
constexpr std::size_t kParallelMinPoints = 1000000;
// Cells of the local model farther than this from any cell with points are not grown.
constexpr std::int64_t kReachCells = 4;

// Voxel flags.
constexpr std::uint8_t kFlat = 1;  // enough points and a small height range (paper)
constexpr std::uint8_t kSeed = 2;  // ground seed candidate of the local model

// Weighted first and second moments of (x, y, z) for height-field plane fits.
struct Moments {
  double w = 0, x = 0, y = 0, z = 0, xx = 0, xy = 0, yy = 0, xz = 0, yz = 0;
  void add(double px, double py, double pz, double pw) {
    w += pw;
    x += pw * px;
    y += pw * py;
    z += pw * pz;
    xx += pw * px * px;
    xy += pw * px * py;
    yy += pw * py * py;
    xz += pw * px * pz;
    yz += pw * py * pz;
  }
  void add(const Moments& o) {
    w += o.w;
    x += o.x;
    y += o.y;
    z += o.z;
    xx += o.xx;
    xy += o.xy;
    yy += o.yy;
    xz += o.xz;
    yz += o.yz;
  }
};

// Ground surface z = a x + b y + c (coordinates relative to the cloud's min corner).
struct HeightPlane {
  double a = 0, b = 0, c = 0;
  double at(double x, double y) const { return a * x + b * y + c; }
};

// Least-squares z = a x + b y + c of the moments, the slope pulled towards (a0, b0) with weight
// `lambda` [weight m^2]. Needs m.w > 0.
HeightPlane fitHeightPlane(const Moments& m, double a0, double b0, double lambda) {
  const double mx = m.x / m.w, my = m.y / m.w, mz = m.z / m.w;
  const double cxx = m.xx - m.w * mx * mx + lambda, cxy = m.xy - m.w * mx * my;
  const double cyy = m.yy - m.w * my * my + lambda;
  const double rx = m.xz - m.w * mx * mz + lambda * a0, ry = m.yz - m.w * my * mz + lambda * b0;
  const double det = cxx * cyy - cxy * cxy;
  HeightPlane out;
  if (det > 1e-18) {
    out.a = (cyy * rx - cxy * ry) / det;
    out.b = (cxx * ry - cxy * rx) / det;
  } else {
    out.a = a0;
    out.b = b0;
  }
  out.c = mz - out.a * mx - out.b * my;
  return out;
}

std::uint32_t findRoot(std::uint32_t* uf, std::uint32_t i) {
  while (uf[i] != i) {
    uf[i] = uf[uf[i]];
    i = uf[i];
  }
  return i;
}

// Joins two sets; the smaller index becomes the root, so labels do not depend on visit order.
void unite(std::uint32_t* uf, std::uint32_t a, std::uint32_t b) {
  a = findRoot(uf, a);
  b = findRoot(uf, b);
  if (a < b) {
    uf[b] = a;
  } else if (b < a) {
    uf[a] = b;
  }
}

// LSD radix sort plan for the bits [lo, lo + bits) of 64-bit words: as few passes as digits of at
// most kMaxDigitBits allow. Histograms of all passes are counted by the caller while it writes
// the keys (one read less).
struct RadixPlan {
  int lo = 0, passes = 0, digit = 1;
  std::uint32_t mask() const { return (1u << digit) - 1; }
};

RadixPlan planRadix(int lo, int bits) {
  RadixPlan plan;
  plan.lo = lo;
  plan.passes = std::max(1, (bits + kMaxDigitBits - 1) / kMaxDigitBits);
  plan.digit = std::max(1, (bits + plan.passes - 1) / plan.passes);
  return plan;
}

// Scatter passes of the radix sort of `a` (with `b` alongside when not null); `hist` holds the
// digit counts of every pass (passes << digit entries). Passes whose digit is constant are skipped.
template <typename B>
void radixScatter(const RadixPlan& plan, std::vector<std::uint32_t>* hist,
                  std::vector<std::uint64_t>* a, std::vector<std::uint64_t>* a_tmp,
                  std::vector<B>* b, std::vector<B>* b_tmp) {
  const std::size_t n = a->size();
  const std::uint32_t mask = plan.mask();
  a_tmp->resize(n);
  if (b) b_tmp->resize(n);
  for (int q = 0; q < plan.passes; ++q) {
    const int shift = plan.lo + q * plan.digit;
    std::uint32_t* h = hist->data() + (static_cast<std::size_t>(q) << plan.digit);
    if (h[((*a)[0] >> shift) & mask] == n) continue;  // every key has this digit
    std::uint32_t sum = 0;
    for (std::uint32_t j = 0; j <= mask; ++j) {
      const std::uint32_t cnt = h[j];
      h[j] = sum;
      sum += cnt;
    }
    const std::uint64_t* k = a->data();
    std::uint64_t* kt = a_tmp->data();
    if (b) {
      const B* o = b->data();
      B* ot = b_tmp->data();
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t dst = h[(k[i] >> shift) & mask]++;
        kt[dst] = k[i];
        ot[dst] = o[i];
      }
      b->swap(*b_tmp);
    } else {
      for (std::size_t i = 0; i < n; ++i) kt[h[(k[i] >> shift) & mask]++] = k[i];
    }
    a->swap(*a_tmp);
  }
}

}  // namespace

struct VoxelGroundFilter::Impl {
  // Voxel key layout: x | y | z bit fields, z lowest, so a column's voxels are consecutive.
  std::uint64_t nx = 0, ny = 0, nz = 0;
  int shift_x = 0, shift_y = 0;
  std::uint64_t mask_y = 0, mask_z = 0;
  bool packed = false;  // keys hold (voxel key << 32 | slot)
  bool all_valid = false;

  // Per valid point in input order ("slot").
  std::vector<std::uint32_t> point_index;  // slot -> input index (unused when all are valid)
  std::vector<float> pxyz;                 // x y z triplets (absolute, then relative to the min)
  std::vector<std::uint64_t> keys, keys_tmp;
  std::vector<std::uint32_t> order, order_tmp;  // sorted position -> slot (unpacked keys)
  RadixPlan plan;
  std::vector<std::uint32_t> hist;  // digit counts of the radix passes

  // Per valid point in voxel-key order.
  std::vector<float> sx, sy, sz;
  std::vector<std::uint8_t> ground;

  // Per voxel (sorted by key).
  std::vector<std::uint64_t> vkey;
  std::vector<std::uint32_t> vstart;  // CSR into the sorted points, size V + 1
  std::vector<float> vx, vy, vz;      // centroid
  std::vector<std::uint8_t> vflags;
  std::vector<std::uint32_t> vcell;    // ground-model cell
  std::vector<std::uint32_t> vground;  // ground points after classification
  std::vector<std::uint32_t> vsum_g, vsum_n;

  // Columns (x, y): runs of voxels.
  std::vector<std::uint64_t> col_key;    // voxel key >> shift_y
  std::vector<std::uint32_t> col_first;  // first voxel, size columns + 1

  // Flat voxels and their segments.
  std::vector<std::uint32_t> flat;  // voxel ids of the flat voxels kept, key order
  std::vector<std::uint32_t> uf;    // union-find parents, indexed like `flat`
  std::vector<std::uint32_t> seg_voxels;
  std::vector<std::uint64_t> seg_points;

  // Cells of the local ground model.
  struct Seed {
    float x, y, z, w;
  };
  std::vector<std::uint32_t> seeds;  // seed candidate voxels, key order
  std::uint64_t cell_vox = 1, ncx = 1, ncy = 1;
  std::size_t cell_count_total = 1;
  std::vector<std::uint32_t> cell_of_x, cell_of_y;  // voxel x -> cell x * ncy, voxel y -> cell y
  std::vector<std::uint32_t> cell_start, cell_fill;
  std::vector<Seed> cell_seeds;
  std::vector<std::uint8_t> cell_used;  // holds voxels
  std::vector<Moments> cell_mom;
  std::vector<HeightPlane> cell_plane, cell_final;
  std::vector<std::uint32_t> cell_parent;       // cell that queued it
  std::vector<float> cell_cos;                  // cos of the final plane's slope
  std::vector<std::uint8_t> cell_state;         // 0 new, 1 queued, 2 done, 3 done with seeds
  std::vector<std::uint32_t> queue, queue_far;  // cells to grow: next to seeds, others
  std::vector<std::uint8_t> near_q;             // cell waits in `queue`
  std::vector<std::uint8_t> reach;              // within kReachCells of a cell with points
  std::vector<double> cell_mu, cell_sigma;
  std::vector<std::uint64_t> cell_count;

  // Vote.
  struct ColInfo {
    std::int32_t base, ext;    // z prefix range base .. base + ext - 1; ext < 0: scan voxels
    std::uint32_t pool;        // offset of the prefix sums in `pre` (pairs)
    std::uint32_t first, end;  // voxels
  };
  std::vector<ColInfo> col_info;        // + one empty sentinel
  std::vector<std::uint32_t> pre;       // z prefix sums of (ground, all) points
  std::vector<std::uint8_t> col_built;  // prefix sums of the column are in `pre`
  struct ZRange {
    std::int32_t glo, ghi, nlo, nhi;  // z of the lowest/highest voxel with ground/non-ground points
  };
  static constexpr std::int32_t kNoLo = std::numeric_limits<std::int32_t>::max() / 2;
  static constexpr std::int32_t kNoHi = -kNoLo;
  std::vector<ZRange> col_range, range_rows;
  std::vector<std::int32_t> col_alo, col_ahi;  // z range of the voxels voted, per column
  std::vector<std::int32_t> row_slots;

  /// Valid points, bounds, keys. Returns the number of valid points.
  std::size_t prepare(const CloudView& cloud, double vs);
  /// Sorts the points by voxel key and builds the voxels, their flags and the columns.
  void voxelize(const VoxelGroundFilterParams& p);
  /// Cell grid of the local model (one cell for the global plane) and the per-axis lookups.
  void setupCells(const VoxelGroundFilterParams& p);
  /// Region growing over the kept flat voxels; returns the root of the largest segment or -1.
  std::int64_t segment(const VoxelGroundFilterParams& p);
  /// Plane of the largest segment not steeper than max_slope_deg; updates `best` to its root.
  /// Returns false when there is no flat segment.
  bool globalPlane(const VoxelGroundFilterParams& p, std::int64_t* best, HeightPlane* gp);
  /// Cell planes of the local ground model grown from the plane of the largest segment.
  void growCells(const VoxelGroundFilterParams& p, const HeightPlane& global, std::int64_t best);
  /// Point-weighted majority of the 26-neighbourhood (and the voxel itself) per voxel.
  void vote();
  /// Calls visit(q, r0, r1, r2) for every column q with pointers into three rows of column ids
  /// (x - 1, x, x + 1; entry y + 1 is column y; `col_key.size()` where there is none).
  template <typename Visit>
  void sweepColumns(Visit&& visit);
};

VoxelGroundFilter::VoxelGroundFilter(const VoxelGroundFilterParams& params)
    : params_(params), impl_(std::make_unique<Impl>()) {
  params_.validate();
}

VoxelGroundFilter::~VoxelGroundFilter() = default;

std::size_t VoxelGroundFilter::Impl::prepare(const CloudView& cloud, double vs) {
  const std::size_t n_in = cloud.size();
  // Valid points compacted (x y z triplets) and their bounds.
  point_index.resize(n_in);
  pxyz.resize(3 * n_in);
  std::uint32_t* idx = point_index.data();
  float* out = pxyz.data();
  float minx = std::numeric_limits<float>::max(), miny = minx, minz = minx;
  float maxx = -minx, maxy = -minx, maxz = -minx;
  std::size_t n = 0;
  for (std::size_t i = 0; i < n_in; ++i) {
    const float x = cloud.x(i), y = cloud.y(i), z = cloud.z(i);
    // x - x is 0 for finite x and NaN for NaN/Inf: one test for all three.
    if (!((x - x) + (y - y) + (z - z) == 0.f)) continue;
    idx[n] = static_cast<std::uint32_t>(i);
    out[3 * n] = x;
    out[3 * n + 1] = y;
    out[3 * n + 2] = z;
    ++n;
    minx = x < minx ? x : minx;
    miny = y < miny ? y : miny;
    minz = z < minz ? z : minz;
    maxx = x > maxx ? x : maxx;
    maxy = y > maxy ? y : maxy;
    maxz = z > maxz ? z : maxz;
  }
  all_valid = n == n_in;
  if (n == 0) return 0;
  nx = static_cast<std::uint64_t>((static_cast<double>(maxx) - minx) / vs) + 1;
  ny = static_cast<std::uint64_t>((static_cast<double>(maxy) - miny) / vs) + 1;
  nz = static_cast<std::uint64_t>((static_cast<double>(maxz) - minz) / vs) + 1;
  const int bx = bitsFor(nx), by = bitsFor(ny), bz = bitsFor(nz);
  if (bx > kMaxAxisBits || by > kMaxAxisBits || bz > kMaxAxisBits) {
    std::ostringstream os;
    os << "cloud extent " << (maxx - minx) << " x " << (maxy - miny) << " x " << (maxz - minz)
       << " m is too large for voxel_size " << vs << " m (at most " << (1u << kMaxAxisBits)
       << " voxels per axis)";
    throw std::runtime_error(os.str());
  }
  shift_y = bz;
  shift_x = by + bz;
  mask_z = (std::uint64_t{1} << bz) - 1;
  mask_y = (std::uint64_t{1} << by) - 1;
  // Sorting (key << 32 | slot) words moves 8 bytes a point instead of 12 when the key fits.
  packed = bx + by + bz <= 32;

  // Coordinates relative to the minimum (keeps float precision far from the origin: UTM, TLS),
  // voxel keys and the digit counts of the radix sort.
  keys.resize(n);
  if (!packed) order.resize(n);
  plan = planRadix(packed ? 32 : 0, bx + by + bz);
  hist.assign(static_cast<std::size_t>(plan.passes) << plan.digit, 0);
  std::uint64_t* k_out = keys.data();
  std::uint32_t* o_out = order.data();
  std::uint32_t* h = hist.data();
  const float inv_vs = static_cast<float>(1.0 / vs);
  const std::uint32_t lx = static_cast<std::uint32_t>(nx - 1),
                      ly = static_cast<std::uint32_t>(ny - 1),
                      lz = static_cast<std::uint32_t>(nz - 1);
  const int sx_ = shift_x, sy_ = shift_y;
  const int passes = plan.passes, digit = plan.digit, lo = plan.lo;
  const std::uint32_t dmask = plan.mask();
  const bool pk = packed;
  for (std::size_t s = 0; s < n; ++s) {
    const float x = out[3 * s] - minx, y = out[3 * s + 1] - miny, z = out[3 * s + 2] - minz;
    out[3 * s] = x;
    out[3 * s + 1] = y;
    out[3 * s + 2] = z;
    const std::uint64_t ix = std::min(static_cast<std::uint32_t>(x * inv_vs), lx);
    const std::uint64_t iy = std::min(static_cast<std::uint32_t>(y * inv_vs), ly);
    const std::uint64_t iz = std::min(static_cast<std::uint32_t>(z * inv_vs), lz);
    const std::uint64_t key = (ix << sx_) | (iy << sy_) | iz;
    std::uint64_t word;
    if (pk) {
      word = (key << 32) | s;
      k_out[s] = word;
    } else {
      word = key;
      k_out[s] = key;
      o_out[s] = static_cast<std::uint32_t>(s);
    }
    word >>= lo;
    ++h[word & dmask];
    if (passes > 1) ++h[(std::size_t{1} << digit) + ((word >> digit) & dmask)];
    for (int q = 2; q < passes; ++q) {
      ++h[(static_cast<std::size_t>(q) << digit) + ((word >> (q * digit)) & dmask)];
    }
  }
  return n;
}

void VoxelGroundFilter::Impl::setupCells(const VoxelGroundFilterParams& p) {
  // Local planes: cells of tile_size with a border of one cell around the grid (3 x 3
  // neighbourhoods then need no bounds checks).
  std::uint64_t border = 0;
  if (p.local_planes) {
    cell_vox = std::max<std::uint64_t>(1, std::llround(p.tile_size / p.voxel_size));
    constexpr std::uint64_t kMaxCells = std::uint64_t{1} << 22;  // memory cap for huge extents
    while (((nx + cell_vox - 1) / cell_vox + 2) * ((ny + cell_vox - 1) / cell_vox + 2) >
           kMaxCells) {
      cell_vox *= 2;
    }
    border = 1;
    ncx = (nx + cell_vox - 1) / cell_vox + 2;
    ncy = (ny + cell_vox - 1) / cell_vox + 2;
  } else {
    cell_vox = std::max(nx, ny);
    ncx = ncy = 1;
  }
  cell_count_total = ncx * ncy;
  cell_of_x.resize(nx);
  cell_of_y.resize(ny);
  for (std::uint64_t i = 0; i < nx; ++i) {
    cell_of_x[i] = static_cast<std::uint32_t>((i / cell_vox + border) * ncy);
  }
  for (std::uint64_t i = 0; i < ny; ++i) {
    cell_of_y[i] = static_cast<std::uint32_t>(i / cell_vox + border);
  }
}

bool VoxelGroundFilter::Impl::globalPlane(const VoxelGroundFilterParams& p, std::int64_t* best,
                                          HeightPlane* gp) {
  if (*best < 0) return false;
  // The plane of the largest segment that is not steeper than max_slope_deg: the largest one can
  // be a wall scanned line by line (its flat voxels stack up), see README.
  constexpr int kCandidates = 8;
  std::array<std::uint32_t, kCandidates> cand{};
  int ncand = 0;
  auto better = [&](std::uint32_t a, std::uint32_t b) {
    return seg_voxels[a] != seg_voxels[b] ? seg_voxels[a] > seg_voxels[b]
                                          : seg_points[a] > seg_points[b];
  };
  for (std::size_t j = 0; j < flat.size(); ++j) {  // the largest segments, by voxels then points
    if (uf[j] != j) continue;
    int pos = ncand;
    while (pos > 0 && better(static_cast<std::uint32_t>(j), cand[pos - 1])) --pos;
    if (pos >= kCandidates) continue;
    for (int q = std::min(ncand, kCandidates - 1); q > pos; --q) cand[q] = cand[q - 1];
    cand[pos] = static_cast<std::uint32_t>(j);
    ncand = std::min(ncand + 1, kCandidates);
  }
  std::array<PlaneAccumulator, kCandidates> acc;
  std::array<double, kCandidates> zsum{}, cnt{};
  for (std::size_t j = 0; j < flat.size(); ++j) {
    int q = 0;
    while (q < ncand && cand[q] != uf[j]) ++q;
    if (q == ncand) continue;
    const std::uint32_t v = flat[j];
    for (std::uint32_t k = vstart[v]; k < vstart[v + 1]; ++k) {
      acc[q].add(sx[k], sy[k], sz[k]);
      zsum[q] += sz[k];
      cnt[q] += 1.0;
    }
  }
  const double min_nz = std::cos(p.max_slope_deg * M_PI / 180.0);
  Plane plane;
  for (int q = 0; q < ncand; ++q) {
    if (acc[q].fit(&plane) && plane.normal.z() >= min_nz) {
      *best = cand[q];
      gp->a = -plane.normal.x() / plane.normal.z();
      gp->b = -plane.normal.y() / plane.normal.z();
      gp->c = -plane.d / plane.normal.z();
      return true;
    }
  }
  *gp = HeightPlane();
  gp->c = zsum[0] / cnt[0];  // no sub-horizontal plane (one scan line): level, through the largest
  return true;
}

void VoxelGroundFilter::Impl::voxelize(const VoxelGroundFilterParams& p) {
  const std::size_t n = keys.size();
  if (packed) {
    radixScatter<std::uint32_t>(plan, &hist, &keys, &keys_tmp, nullptr, nullptr);
  } else {
    radixScatter(plan, &hist, &keys, &keys_tmp, &order, &order_tmp);
  }

  // One pass over the sorted points: coordinates in key order, runs of equal keys become voxels.
  // A voxel is finished when the next one starts (its flags need the next key).
  sx.resize(n);
  sy.resize(n);
  sz.resize(n);
  vkey.resize(n);
  vstart.resize(n + 1);
  vx.resize(n);
  vy.resize(n);
  vz.resize(n);
  vflags.resize(n);
  vcell.resize(n);
  col_key.clear();
  col_first.clear();
  flat.clear();
  seeds.clear();
  cell_used.assign(cell_count_total, 0);
  const std::uint64_t* k = keys.data();
  const std::uint32_t* o = order.data();
  const float* in = pxyz.data();
  float* x_out = sx.data();
  float* y_out = sy.data();
  float* z_out = sz.data();
  std::uint64_t* vk = vkey.data();
  std::uint32_t* vs = vstart.data();
  const std::uint32_t* cxt = cell_of_x.data();
  const std::uint32_t* cyt = cell_of_y.data();
  const std::uint32_t min_pts = static_cast<std::uint32_t>(p.min_points_per_voxel);
  const float flat_thr = static_cast<float>(p.flatness_threshold);
  const bool pk = packed;
  const int sy_ = shift_y, sx_ = shift_x;
  const bool local = p.local_planes;
  const std::uint64_t my = mask_y, mz = mask_z;
  std::size_t nv = 0;
  float zmin = 0.f, zmax = 0.f, xsum = 0.f, ysum = 0.f, zsum = 0.f;
  // Finishes voxel v (points [vs[v], end)); `next` is the key of the following voxel, if any.
  auto finish = [&](std::size_t v, std::uint32_t end, bool has_next, std::uint64_t next) {
    const std::uint32_t cnt = end - vs[v];
    const float inv = 1.f / static_cast<float>(cnt);
    vx[v] = xsum * inv;
    vy[v] = ysum * inv;
    vz[v] = zsum * inv;
    const std::uint64_t key = vk[v];
    const std::uint64_t col = key >> sy_;
    // ---- flat voxels (paper): enough points and a small height range.
    const bool is_flat = cnt >= min_pts && zmax - zmin < flat_thr;
    // ---- seed candidates of the local model: the lowest voxel of its column with free space
    // above it, flat or too sparse to tell (far, sparse ground).
    const bool lowest = v == 0 || (vk[v - 1] >> sy_) != col;
    const bool clear =
        !has_next || (next >> sy_) != col || (next & mz) - (key & mz) > kSeedClearanceVoxels;
    const bool is_seed = (is_flat || cnt < min_pts) && lowest && clear;
    vflags[v] = static_cast<std::uint8_t>((is_flat ? kFlat : 0) | (is_seed ? kSeed : 0));
    const std::uint32_t cell = cxt[key >> sx_] + cyt[col & my];
    vcell[v] = cell;
    cell_used[cell] = 1;
    if (lowest) {
      col_key.push_back(col);
      col_first.push_back(static_cast<std::uint32_t>(v));
    }
    // Region growing input: every flat voxel (paper) for the global plane; for the local model
    // only the flat seed candidates (the same components on the ground, 3x less work, and wall
    // voxels stacked line over line drop out).
    if (is_flat && (is_seed || !local)) flat.push_back(static_cast<std::uint32_t>(v));
    if (is_seed) seeds.push_back(static_cast<std::uint32_t>(v));
  };
  constexpr std::size_t kAhead = 16;  // prefetch distance of the random coordinate reads
  for (std::size_t i = 0; i < n; ++i) {
    if (i + kAhead < n) {
      const std::uint32_t ps = pk ? static_cast<std::uint32_t>(k[i + kAhead]) : o[i + kAhead];
      __builtin_prefetch(in + 3 * static_cast<std::size_t>(ps));
    }
    const std::uint64_t key = pk ? k[i] >> 32 : k[i];
    const std::uint32_t s = pk ? static_cast<std::uint32_t>(k[i]) : o[i];
    const float x = in[3 * s], y = in[3 * s + 1], z = in[3 * s + 2];
    x_out[i] = x;
    y_out[i] = y;
    z_out[i] = z;
    if (nv == 0 || key != vk[nv - 1]) {
      if (nv > 0) finish(nv - 1, static_cast<std::uint32_t>(i), true, key);
      vk[nv] = key;
      vs[nv++] = static_cast<std::uint32_t>(i);
      zmin = zmax = z;
      xsum = ysum = zsum = 0.f;
    }
    zmin = std::min(zmin, z);
    zmax = std::max(zmax, z);
    xsum += x;
    ysum += y;
    zsum += z;
  }
  finish(nv - 1, static_cast<std::uint32_t>(n), false, 0);
  vs[nv] = static_cast<std::uint32_t>(n);
  vkey.resize(nv);
  vstart.resize(nv + 1);
  col_first.push_back(static_cast<std::uint32_t>(nv));
}

std::int64_t VoxelGroundFilter::Impl::segment(const VoxelGroundFilterParams& p) {
  // `flat` holds the flat voxels (voxelize; with local planes only the flat seed candidates).
  // ---- height filter (paper, global plane only): flat voxels higher than the mean flat-voxel
  // height + margin are not ground seeds. The local model has its own, local, windows.
  if (!p.local_planes && !flat.empty()) {
    double flat_z_sum = 0.0;
    for (std::uint32_t v : flat) flat_z_sum += vz[v];
    const double cut = flat_z_sum / flat.size() + p.height_margin;
    std::size_t k = 0;
    for (std::uint32_t v : flat) {
      if (vz[v] < cut) flat[k++] = v;
    }
    flat.resize(k);
  }
  // ---- region growing over the flat voxels (26-adjacency) as union-find: each flat voxel is
  // joined with the flat voxels among its 13 neighbours with smaller keys: row x - 1 (columns
  // y - 1 .. y + 1), column y - 1 of its own row, and the voxel below it. Rows of flat-column ids
  // (two buffers, x parity) replace any search.
  const std::size_t nf = flat.size();
  uf.resize(nf);
  std::uint32_t* u = uf.data();
  for (std::size_t i = 0; i < nf; ++i) u[i] = static_cast<std::uint32_t>(i);
  const std::uint32_t* fl = flat.data();
  const std::uint64_t* vk = vkey.data();
  const std::size_t stride = ny + 2;
  row_slots.assign(2 * stride, -1);
  std::int32_t* rows = row_slots.data();
  std::array<std::int64_t, 2> held_x = {-1, -1};
  std::array<std::size_t, 2> held_b{}, held_e{};  // flat index range of the row a buffer holds
  const int sy_ = shift_y;
  const std::uint64_t my = mask_y, mz = mask_z;
  std::size_t i = 0;
  while (i < nf) {
    const std::uint64_t x = vk[fl[i]] >> shift_x;
    std::size_t e = i;
    while (e < nf && (vk[fl[e]] >> shift_x) == x) ++e;
    // This row's buffer: clear the row it held, fill with this row's first flat voxel per y.
    const int k = static_cast<int>(x & 1);
    std::int32_t* cur = rows + k * stride + 1;
    for (std::size_t j = held_b[k]; j < held_e[k]; ++j) cur[(vk[fl[j]] >> sy_) & my] = -1;
    for (std::size_t j = e; j-- > i;) cur[(vk[fl[j]] >> sy_) & my] = static_cast<std::int32_t>(j);
    held_x[k] = static_cast<std::int64_t>(x);
    held_b[k] = i;
    held_e[k] = e;
    const bool has_prev = x > 0 && held_x[k ^ 1] == static_cast<std::int64_t>(x - 1);
    const std::int32_t* prev = rows + (k ^ 1) * stride + 1;
    for (std::size_t a = i; a < e; ++a) {
      const std::uint64_t key = vk[fl[a]];
      const std::uint64_t col = key >> sy_;
      const std::int64_t y = static_cast<std::int64_t>(col & my);
      const std::int64_t z = static_cast<std::int64_t>(key & mz);
      // Same column, one step below.
      if (a > i && (vk[fl[a - 1]] >> sy_) == col &&
          z - static_cast<std::int64_t>(vk[fl[a - 1]] & mz) == 1) {
        unite(u, static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(a - 1));
      }
      // Neighbour columns: (x, y - 1) and (x - 1, y - 1 .. y + 1).
      std::int32_t nbs[4] = {cur[y - 1], has_prev ? prev[y - 1] : -1, has_prev ? prev[y] : -1,
                             has_prev ? prev[y + 1] : -1};
      for (std::int32_t f : nbs) {
        if (f < 0) continue;
        const std::uint64_t fcol = vk[fl[f]] >> sy_;
        for (std::size_t b = static_cast<std::size_t>(f); b < nf && (vk[fl[b]] >> sy_) == fcol;
             ++b) {
          const std::int64_t dz = static_cast<std::int64_t>(vk[fl[b]] & mz) - z;
          if (dz > 1) break;
          if (dz >= -1) unite(u, static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
        }
      }
    }
    i = e;
  }
  // Largest segment: most voxels (its area; robust to many duplicate points), then most points.
  seg_voxels.assign(nf, 0);
  seg_points.assign(nf, 0);
  for (std::size_t j = 0; j < nf; ++j) {
    const std::uint32_t r = findRoot(u, static_cast<std::uint32_t>(j));
    u[j] = r;  // flattened: uf[j] is the segment id (its root) from here on
    ++seg_voxels[r];
    seg_points[r] += vstart[fl[j] + 1] - vstart[fl[j]];
  }
  std::int64_t best = -1;
  for (std::size_t j = 0; j < nf; ++j) {
    if (u[j] != j) continue;
    if (best < 0 || seg_voxels[j] > seg_voxels[best] ||
        (seg_voxels[j] == seg_voxels[best] && seg_points[j] > seg_points[best])) {
      best = static_cast<std::int64_t>(j);
    }
  }
  return best;
}

void VoxelGroundFilter::Impl::growCells(const VoxelGroundFilterParams& p, const HeightPlane& gp,
                                        std::int64_t best) {
  const std::size_t nc = ncx * ncy;
  const std::uint32_t* vs = vstart.data();
  const std::uint32_t* vc = vcell.data();
  // Seed candidates per cell (CSR, coordinates copied for sequential access); start cell = most
  // voxels of the largest segment.
  cell_start.assign(nc + 1, 0);
  for (std::uint32_t v : seeds) ++cell_start[vc[v] + 1];
  for (std::size_t c = 0; c < nc; ++c) cell_start[c + 1] += cell_start[c];
  cell_seeds.resize(seeds.size());
  cell_fill.assign(cell_start.begin(), cell_start.end() - 1);
  for (std::uint32_t v : seeds) {
    cell_seeds[cell_fill[vc[v]]++] =
        Seed{vx[v], vy[v], vz[v], static_cast<float>(vs[v + 1] - vs[v])};
  }
  std::vector<std::uint32_t>& seg_in_cell = cell_fill;  // reused
  seg_in_cell.assign(nc, 0);
  for (std::size_t i = 0; i < flat.size(); ++i) {
    if (uf[i] == static_cast<std::uint32_t>(best)) ++seg_in_cell[vc[flat[i]]];
  }
  const std::size_t start =
      std::max_element(seg_in_cell.begin(), seg_in_cell.end()) - seg_in_cell.begin();

  // Growth from the start cell. Each cell predicts its ground from the seeds accepted by its
  // finished neighbours (slope pulled towards level: a tilted prior extrapolates badly across
  // gaps), takes as seeds the candidates from height_margin below to seed_window above that
  // prediction (the ground is the lowest surface: lower candidates are safe, higher ones may be
  // objects), refits, keeps the seeds within plane_distance of the refit, and refits again. The
  // grid has a border of one cell (state "done", never seeded) so the 3 x 3 neighbourhoods need no
  // bounds checks.
  const double cs = static_cast<double>(cell_vox) * p.voxel_size;  // cell edge [m]
  const double lambda = kSlopePriorWeight * cs * cs;
  const double max_grad = std::tan(p.max_slope_deg * M_PI / 180.0);
  const double max_grad2 = max_grad * max_grad;
  const std::int64_t stride = static_cast<std::int64_t>(ncy);  // includes the border
  const std::int64_t nb_off[9] = {-stride - 1, -stride,    -stride + 1, -1,        0,
                                  1,           stride - 1, stride,      stride + 1};
  cell_mom.resize(nc);
  cell_plane.assign(nc, gp);  // cells never grown (no seeds beyond reach) keep the global plane
  cell_parent.resize(nc);
  cell_state.assign(nc, 0);
  near_q.assign(nc, 0);
  std::uint8_t* state = cell_state.data();
  // Cells farther than kReachCells from any cell with points are never grown (state "done"):
  // they would only carry the prediction across empty space. Data beyond such a stretch are
  // grown again from a new start (below). The border is "done" too.
  reach.assign(nc, 0);
  for (std::uint64_t x = 0; x < ncx; ++x) {  // dilate along y, then along x
    const std::uint8_t* used = cell_used.data() + x * ncy;
    std::uint8_t* r = reach.data() + x * ncy;
    std::int64_t last = -(kReachCells + 1);
    for (std::int64_t y = 0; y < static_cast<std::int64_t>(ncy); ++y) {
      if (used[y]) last = y;
      if (y - last <= kReachCells) r[y] = 1;
    }
    last = static_cast<std::int64_t>(ncy) + kReachCells + 1;
    for (std::int64_t y = static_cast<std::int64_t>(ncy) - 1; y >= 0; --y) {
      if (used[y]) last = y;
      if (last - y <= kReachCells) r[y] = 1;
    }
  }
  for (std::uint64_t y = 0; y < ncy; ++y) {
    std::int64_t last = -(kReachCells + 1);
    for (std::int64_t x = 0; x < static_cast<std::int64_t>(ncx); ++x) {
      if (reach[x * ncy + y] & 1) last = x;
      if (x - last <= kReachCells) reach[x * ncy + y] |= 2;
    }
    last = static_cast<std::int64_t>(ncx) + kReachCells + 1;
    for (std::int64_t x = static_cast<std::int64_t>(ncx) - 1; x >= 0; --x) {
      if (reach[x * ncy + y] & 1) last = x;
      if (last - x <= kReachCells) reach[x * ncy + y] |= 2;
    }
  }
  for (std::size_t t = 0; t < nc; ++t) {
    if (!(reach[t] & 2)) state[t] = 2;
  }
  for (std::uint64_t x = 0; x < ncx; ++x) {
    state[x * ncy] = state[x * ncy + ncy - 1] = 2;
  }
  for (std::uint64_t y = 0; y < ncy; ++y) {
    state[y] = state[(ncx - 1) * ncy + y] = 2;
  }
  // Two FIFO queues: cells next to a cell with accepted seeds first ("near"), the rest after
  // ("far"), so the model grows where there is evidence and crosses empty stretches (the
  // sensor's blind circle, shadows) last, from all sides.
  queue.clear();
  queue_far.clear();
  queue.push_back(static_cast<std::uint32_t>(start));
  // The start cell's prediction: the largest segment's voxels in it (level slope prior), so a
  // tilted global plane cannot put it off the ground it was chosen for.
  {
    Moments sm;
    for (std::size_t i = 0; i < flat.size(); ++i) {
      const std::uint32_t v = flat[i];
      if (uf[i] == static_cast<std::uint32_t>(best) && vc[v] == start) {
        sm.add(vx[v], vy[v], vz[v], static_cast<double>(vs[v + 1] - vs[v]));
      }
    }
    cell_plane[start] = sm.w > 0 ? fitHeightPlane(sm, 0.0, 0.0, lambda) : gp;
  }
  cell_parent[start] = static_cast<std::uint32_t>(start);
  state[start] = 1;
  const Seed* seeds = cell_seeds.data();
  Moments* mom = cell_mom.data();
  HeightPlane* plane = cell_plane.data();
  std::uint32_t* parent = cell_parent.data();
  const std::uint32_t* cst = cell_start.data();
  std::size_t qn = 0, qf = 0, next_island = 0;
  const std::uint32_t ncy32 = static_cast<std::uint32_t>(ncy);
  for (;;) {
    std::uint32_t t;
    if (qn < queue.size()) {
      t = queue[qn++];
    } else if (qf < queue_far.size()) {
      t = queue_far[qf++];
    } else {
      // Cells with points not reached (beyond an empty stretch): grow again from the first of
      // them with seeds, predicted level through its lowest seed (the ground is the lowest
      // surface); cells without seeds left over keep the global plane.
      while (next_island < nc && !(cell_used[next_island] && state[next_island] == 0 &&
                                   cst[next_island + 1] > cst[next_island])) {
        ++next_island;
      }
      if (next_island == nc) break;
      t = static_cast<std::uint32_t>(next_island);
      float zlow = std::numeric_limits<float>::max();
      for (std::uint32_t k = cst[t]; k < cst[t + 1]; ++k) zlow = std::min(zlow, seeds[k].z);
      plane[t] = HeightPlane();
      plane[t].c = zlow;
      parent[t] = t;
      state[t] = 1;
    }
    if (state[t] >= 2) continue;  // queued twice (far, then near)
    const std::uint32_t s0 = cst[t], s1 = cst[t + 1];
    // Prediction: the parent's height at this cell's centre (level), refined by the seeds of
    // the finished neighbours (also for empty cells: they pass it on).
    const std::uint32_t tx = t / ncy32, ty = t - tx * ncy32;
    const double cx = (tx - 0.5) * cs;  // the border shifts the cell indices by one
    const double cy = (ty - 0.5) * cs;
    HeightPlane pred;
    pred.c = plane[parent[t]].at(cx, cy);
    Moments nb;
    for (int k = 0; k < 9; ++k) {
      const std::size_t u = static_cast<std::size_t>(t + nb_off[k]);
      if (state[u] == 3) nb.add(mom[u]);
    }
    if (nb.w > 0) pred = fitHeightPlane(nb, 0.0, 0.0, lambda);
    HeightPlane cur = pred;
    Moments own;
    if (s1 > s0) {
      double below = p.height_margin, above = p.seed_window;
      for (int pass = 0; pass < 2; ++pass) {
        own = Moments();
        for (std::uint32_t k = s0; k < s1; ++k) {
          const Seed& sd = seeds[k];
          const double dz = sd.z - cur.at(sd.x, sd.y);
          if (dz < above && dz > -below) own.add(sd.x, sd.y, sd.z, sd.w);
        }
        if (own.w <= 0) break;
        Moments tot = nb;
        tot.add(own);
        cur = fitHeightPlane(tot, 0.0, 0.0, lambda);
        below = above = p.plane_distance;
      }
    }
    if (own.w > 0 && cur.a * cur.a + cur.b * cur.b <= max_grad2) {
      mom[t] = own;
      plane[t] = cur;
      state[t] = 3;  // finished with seeds
    } else {
      plane[t] = pred;
      state[t] = 2;  // finished without seeds
    }
    const bool seeded = state[t] == 3;
    for (int k = 0; k < 9; ++k) {
      const std::size_t u = static_cast<std::size_t>(t + nb_off[k]);
      if (state[u] >= 2 || (state[u] == 1 && !seeded)) continue;
      if (seeded) {
        if (state[u] == 1 && near_q[u]) continue;  // already waiting near seeds
        near_q[u] = 1;
        queue.push_back(static_cast<std::uint32_t>(u));
      } else {
        queue_far.push_back(static_cast<std::uint32_t>(u));
      }
      state[u] = 1;
      parent[u] = t;
    }
  }
  // Final planes of the cells holding points: seeds of the 3 x 3 cells around, all sides now
  // known; without seeds around, the grown plane.
  cell_final.resize(nc);
  cell_cos.resize(nc);
  for (std::size_t t = 0; t < nc; ++t) {
    if (!cell_used[t]) continue;
    Moments nb;
    for (int k = 0; k < 9; ++k) {
      const std::size_t u = static_cast<std::size_t>(t + nb_off[k]);
      if (state[u] == 3) nb.add(mom[u]);
    }
    const HeightPlane& g = plane[t];
    const HeightPlane f = nb.w > 0 ? fitHeightPlane(nb, g.a, g.b, lambda) : g;
    cell_final[t] = f;
    cell_cos[t] = static_cast<float>(1.0 / std::sqrt(1.0 + f.a * f.a + f.b * f.b));
  }
}

template <typename Visit>
void VoxelGroundFilter::Impl::sweepColumns(Visit&& visit) {
  const std::size_t ncol = col_key.size();
  const int y_bits = shift_x - shift_y;
  const std::uint64_t y_mask = mask_y;
  const std::uint64_t* ck = col_key.data();
  const std::size_t stride = ny + 2;
  const std::int32_t none = static_cast<std::int32_t>(ncol);
  row_slots.assign(3 * stride, none);
  std::int32_t* sl = row_slots.data();
  std::array<std::int64_t, 3> held_x = {-1, -1, -1};
  std::array<std::size_t, 3> held_b{}, held_e{};
  // Makes the buffer of row rx (rx mod 3) hold columns [b, e) of that row.
  auto put = [&](std::uint64_t rx, std::size_t b, std::size_t e) {
    const int k = static_cast<int>(rx % 3);
    if (held_x[k] == static_cast<std::int64_t>(rx)) return;
    std::int32_t* row = sl + k * stride + 1;
    for (std::size_t q = held_b[k]; q < held_e[k]; ++q) row[ck[q] & y_mask] = none;
    for (std::size_t q = b; q < e; ++q) row[ck[q] & y_mask] = static_cast<std::int32_t>(q);
    held_x[k] = static_cast<std::int64_t>(rx);
    held_b[k] = b;
    held_e[k] = e;
  };
  std::size_t c = 0;
  while (c < ncol) {
    const std::uint64_t x = ck[c] >> y_bits;
    std::size_t ce = c;
    while (ce < ncol && (ck[ce] >> y_bits) == x) ++ce;
    std::size_t ne = ce;
    while (ne < ncol && (ck[ne] >> y_bits) == x + 1) ++ne;
    put(x, c, ce);
    put(x + 1, ce, ne);           // empty when row x + 1 has no columns
    if (x > 0) put(x - 1, 0, 0);  // no-op when row x - 1 was held as a neighbour, else cleared
    // At x == 0 the buffer of "x - 1" was never filled: all none.
    const std::int32_t* r0 = sl + ((x + 2) % 3) * stride;
    const std::int32_t* r1 = sl + (x % 3) * stride;
    const std::int32_t* r2 = sl + ((x + 1) % 3) * stride;
    for (std::size_t q = c; q < ce; ++q) {
      const std::uint64_t y = ck[q] & y_mask;
      visit(q, r0 + y, r1 + y, r2 + y);
    }
    c = ce;
  }
}

void VoxelGroundFilter::Impl::vote() {
  const std::size_t nv = vkey.size();
  const std::size_t ncol = col_key.size();
  const std::uint64_t* vk = vkey.data();
  const std::uint32_t* vs = vstart.data();
  const std::uint32_t* vg = vground.data();  // ground points per voxel (classification)
  const std::uint32_t* cf = col_first.data();
  const std::uint64_t mz = mask_z;
  // A voxel's vote can differ from its own points' labels only when its neighbourhood holds both
  // ground and non-ground points: only voxels within one z step of a ground voxel and of a
  // non-ground voxel of their 3 x 3 columns are voted. Per column: z ranges of the voxels with
  // ground and with non-ground points; grown over y into dense rows, then over x from the rows
  // x - 1, x, x + 1.
  const ZRange kEmpty{kNoLo, kNoHi, kNoLo, kNoHi};
  col_alo.resize(ncol);
  col_ahi.resize(ncol);
  const ZRange* cr = col_range.data();  // per column (classification)
  std::int32_t* alo = col_alo.data();
  std::int32_t* ahi = col_ahi.data();
  {
    const int y_bits = shift_x - shift_y;
    const std::uint64_t y_mask = mask_y;
    const std::uint64_t* ck = col_key.data();
    const std::size_t stride = ny + 2;
    range_rows.assign(3 * stride, kEmpty);
    ZRange* rows = range_rows.data();
    std::array<std::int64_t, 3> held_x = {-1, -1, -1};
    std::array<std::size_t, 3> held_b{}, held_e{};
    auto put = [&](std::uint64_t rx, std::size_t b, std::size_t e) {
      const int k = static_cast<int>(rx % 3);
      if (held_x[k] == static_cast<std::int64_t>(rx)) return;
      ZRange* row = rows + k * stride;  // entry y + 1 is column y
      for (std::size_t q = held_b[k]; q < held_e[k]; ++q) {
        const std::uint64_t y = ck[q] & y_mask;
        row[y] = row[y + 1] = row[y + 2] = kEmpty;
      }
      for (std::size_t q = b; q < e; ++q) {
        const std::uint64_t y = ck[q] & y_mask;
        for (std::uint64_t j = y; j <= y + 2; ++j) {
          row[j].glo = std::min(row[j].glo, cr[q].glo);
          row[j].ghi = std::max(row[j].ghi, cr[q].ghi);
          row[j].nlo = std::min(row[j].nlo, cr[q].nlo);
          row[j].nhi = std::max(row[j].nhi, cr[q].nhi);
        }
      }
      held_x[k] = static_cast<std::int64_t>(rx);
      held_b[k] = b;
      held_e[k] = e;
    };
    std::size_t c = 0;
    while (c < ncol) {
      const std::uint64_t x = ck[c] >> y_bits;
      std::size_t ce = c;
      while (ce < ncol && (ck[ce] >> y_bits) == x) ++ce;
      std::size_t ne = ce;
      while (ne < ncol && (ck[ne] >> y_bits) == x + 1) ++ne;
      put(x, c, ce);
      put(x + 1, ce, ne);
      if (x > 0) put(x - 1, 0, 0);
      const ZRange* r0 = rows + ((x + 2) % 3) * stride;
      const ZRange* r1 = rows + (x % 3) * stride;
      const ZRange* r2 = rows + ((x + 1) % 3) * stride;
      for (std::size_t q = c; q < ce; ++q) {
        const std::uint64_t y = (ck[q] & y_mask) + 1;
        const std::int32_t lo = std::min({r0[y].glo, r1[y].glo, r2[y].glo});
        const std::int32_t hi = std::max({r0[y].ghi, r1[y].ghi, r2[y].ghi});
        const std::int32_t lo2 = std::min({r0[y].nlo, r1[y].nlo, r2[y].nlo});
        const std::int32_t hi2 = std::max({r0[y].nhi, r1[y].nhi, r2[y].nhi});
        alo[q] = std::max(lo, lo2) - 1;
        ahi[q] = std::min(hi, hi2) + 1;
      }
      c = ce;
    }
  }
  // Per column, prefix sums of (ground, all) points over z from its lowest voxel - 1 to its
  // highest + 1: the sums over a z window of three are two loads. Columns with long empty
  // stretches (tree canopy over ground) are scanned instead. Column `ncol` is an empty sentinel.
  col_info.resize(ncol + 1);
  ColInfo* ci = col_info.data();
  std::size_t pool = 0;
  for (std::size_t c = 0; c < ncol; ++c) {
    const std::int32_t z0 = static_cast<std::int32_t>(vk[cf[c]] & mz);
    const std::int32_t z1 = static_cast<std::int32_t>(vk[cf[c + 1] - 1] & mz);
    const std::uint32_t cnt = cf[c + 1] - cf[c];
    ci[c].base = z0 - 1;
    ci[c].pool = static_cast<std::uint32_t>(pool);
    ci[c].first = cf[c];
    ci[c].end = cf[c + 1];
    if (static_cast<std::uint32_t>(z1 - z0) <= 4 * cnt + 8) {
      ci[c].ext = z1 - z0 + 3;
      pool += static_cast<std::size_t>(ci[c].ext) + 1;
    } else {
      ci[c].ext = -1;
    }
  }
  ci[ncol] = ColInfo{0, 0, static_cast<std::uint32_t>(pool), 0, 0};
  pool += 1;
  pre.resize(2 * pool);
  std::uint32_t* pp = pre.data();
  col_built.assign(ncol + 1, 0);
  std::uint8_t* built = col_built.data();
  // Prefix sums of a column, built on first use (only the neighbours of voted voxels need them).
  auto build = [&](std::size_t c) {
    built[c] = 1;
    if (ci[c].ext < 0) return;
    std::uint32_t* q = pp + 2 * ci[c].pool;
    std::uint32_t sg = 0, sn = 0;
    q[0] = q[1] = 0;
    std::uint32_t v = ci[c].first;
    const std::uint32_t e = ci[c].end;
    for (std::int32_t j = 0; j < ci[c].ext; ++j) {
      if (v < e && static_cast<std::int32_t>(vk[v] & mz) == ci[c].base + j) {
        sg += vg[v];
        sn += vs[v + 1] - vs[v];
        ++v;
      }
      q[2 * j + 2] = sg;
      q[2 * j + 3] = sn;
    }
  };
  // Sums over the 3 x 3 x 3 neighbourhood of the voxels that can change.
  vsum_g.resize(nv);
  vsum_n.resize(nv);
  std::uint32_t* sgv = vsum_g.data();
  std::uint32_t* snv = vsum_n.data();
  std::uint8_t* out = ground.data();
  sweepColumns(
      [&](std::size_t q, const std::int32_t* r0, const std::int32_t* r1, const std::int32_t* r2) {
        if (alo[q] > ahi[q]) return;
        const std::int32_t ids[9] = {r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2]};
        const ColInfo* nb[9];
        for (int k = 0; k < 9; ++k) {
          if (!built[ids[k]]) build(static_cast<std::size_t>(ids[k]));
          nb[k] = ci + ids[k];
        }
        for (std::uint32_t v = cf[q]; v < cf[q + 1]; ++v) {
          const std::int32_t z = static_cast<std::int32_t>(vk[v] & mz);
          if (z < alo[q]) continue;
          if (z > ahi[q]) break;
          std::uint32_t g = 0, t = 0;
          for (int k = 0; k < 9; ++k) {
            const ColInfo& d = *nb[k];
            if (d.ext >= 0) {
              const std::int32_t lo = std::min(std::max(z - 1 - d.base, 0), d.ext);
              const std::int32_t hi = std::min(std::max(z + 2 - d.base, lo), d.ext);
              const std::uint32_t* pq = pp + 2 * d.pool;
              g += pq[2 * hi] - pq[2 * lo];
              t += pq[2 * hi + 1] - pq[2 * lo + 1];
            } else {
              for (std::uint32_t u = d.first; u < d.end; ++u) {
                const std::int32_t dz = static_cast<std::int32_t>(vk[u] & mz) - z;
                if (dz >= -1 && dz <= 1) {
                  g += vg[u];
                  t += vs[u + 1] - vs[u];
                }
              }
            }
          }
          sgv[v] = g;
          snv[v] = t;
        }
      });
  // Relabel after all sums (the sums read the classification only).
  for (std::size_t c = 0; c < ncol; ++c) {
    if (alo[c] > ahi[c]) continue;
    for (std::uint32_t v = cf[c]; v < cf[c + 1]; ++v) {
      const std::int32_t z = static_cast<std::int32_t>(vk[v] & mz);
      if (z < alo[c]) continue;
      if (z > ahi[c]) break;
      if (2 * sgv[v] == snv[v]) continue;  // tie: keep the per-point labels
      const std::uint8_t label = 2 * sgv[v] > snv[v] ? 1 : 0;
      for (std::uint32_t k = vs[v]; k < vs[v + 1]; ++k) out[k] = label;
    }
  }
}

void VoxelGroundFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                               FilterStats* stats) {
  const auto t_start = Clock::now();
  Impl& m = *impl_;
  FilterStats local_stats;
  FilterStats& st = stats ? *stats : local_stats;
  st = FilterStats();
  st.input_points = cloud.size();
  labels->assign(cloud.size(), kNonGround);
  const VoxelGroundFilterParams& p = params_;
  const int threads = p.threads > 0 ? p.threads : omp_get_max_threads();

  // ---- 1. valid points, bounds, voxel keys
  auto t0 = Clock::now();
  const std::size_t n = m.prepare(cloud, p.voxel_size);
  st.invalid_points = cloud.size() - n;
  st.stage_ms.emplace_back("prepare", msSince(t0));
  if (n == 0) {
    st.total_ms = msSince(t_start);
    return;
  }
  m.setupCells(p);

  // ---- 2. voxels (sorted keys, runs), 3. flat voxels and seed candidates
  t0 = Clock::now();
  m.voxelize(p);
  const std::size_t nv = m.vkey.size();
  st.stage_ms.emplace_back("voxelize", msSince(t0));

  // ---- 4. height filter, 5. region growing, largest segment
  t0 = Clock::now();
  std::int64_t best = m.segment(p);
  st.stage_ms.emplace_back("segments", msSince(t0));

  // ---- 6. plane of the largest segment (paper), local ground model
  t0 = Clock::now();
  m.ground.assign(n, 0);
  HeightPlane gp;
  const bool have_plane = m.globalPlane(p, &best, &gp);
  const std::size_t nc = m.cell_count_total;
  if (have_plane) {
    if (p.local_planes) {
      m.growCells(p, gp, best);
    } else {
      m.cell_final.assign(1, gp);
      m.cell_cos.assign(1, static_cast<float>(1.0 / std::sqrt(1.0 + gp.a * gp.a + gp.b * gp.b)));
    }
  }
  st.stage_ms.emplace_back("ground_model", msSince(t0));

  // ---- 7. per-point distance to the (cell) plane, optional mean +- std band
  t0 = Clock::now();
  if (have_plane) {
    const float dmax = static_cast<float>(p.plane_distance);
    if (p.std_filter) {
      // Mean and std of the signed distances of the points that shaped each plane: the largest
      // segment (global plane) or the cell's seeds within plane_distance of its plane.
      m.cell_mu.assign(nc, 0.0);
      m.cell_sigma.assign(nc, 0.0);
      m.cell_count.assign(nc, 0);
      auto addVoxel = [&](std::uint32_t v) {
        const std::uint32_t c = m.vcell[v];
        const HeightPlane& hp = m.cell_final[c];
        const double cosf = m.cell_cos[c];
        for (std::uint32_t k = m.vstart[v]; k < m.vstart[v + 1]; ++k) {
          const double d = (m.sz[k] - hp.at(m.sx[k], m.sy[k])) * cosf;
          m.cell_mu[c] += d;
          m.cell_sigma[c] += d * d;
          ++m.cell_count[c];
        }
      };
      if (p.local_planes) {
        for (std::size_t v = 0; v < nv; ++v) {
          if (!(m.vflags[v] & kSeed)) continue;
          const HeightPlane& hp = m.cell_final[m.vcell[v]];
          if (std::abs(m.vz[v] - hp.at(m.vx[v], m.vy[v])) < p.plane_distance) {
            addVoxel(static_cast<std::uint32_t>(v));
          }
        }
      } else {
        for (std::size_t i = 0; i < m.flat.size(); ++i) {
          if (m.uf[i] == static_cast<std::uint32_t>(best)) addVoxel(m.flat[i]);
        }
      }
      for (std::size_t c = 0; c < nc; ++c) {
        const double k = static_cast<double>(m.cell_count[c]);
        const double mu = k > 0 ? m.cell_mu[c] / k : 0.0;
        m.cell_sigma[c] = k > 1 ? std::sqrt(std::max(0.0, m.cell_sigma[c] / k - mu * mu)) : 0.0;
        m.cell_mu[c] = mu;
      }
    }
    const bool band = p.std_filter;
    const double band_k = p.std_multiplier;
    const std::uint32_t* vs = m.vstart.data();
    const std::uint32_t* vc = m.vcell.data();
    const float* x_in = m.sx.data();
    const float* y_in = m.sy.data();
    const float* z_in = m.sz.data();
    const HeightPlane* planes = m.cell_final.data();
    const float* cosines = m.cell_cos.data();
    std::uint8_t* gr = m.ground.data();
    m.vground.resize(nv);
    std::uint32_t* vg = m.vground.data();
    // Column by column (the vote wants each column's z range of voxels with ground and with
    // non-ground points).
    const std::size_t ncol = m.col_key.size();
    m.col_range.resize(ncol);
    Impl::ZRange* cr = m.col_range.data();
    const std::uint32_t* cf = m.col_first.data();
    const std::uint64_t* vk = m.vkey.data();
    const std::uint64_t mz = m.mask_z;
    const float* vxp = m.vx.data();
    const float* vyp = m.vy.data();
#pragma omp parallel for num_threads(threads) \
    schedule(static) if (threads > 1 && n > kParallelMinPoints)
    for (std::size_t col = 0; col < ncol; ++col) {
      Impl::ZRange r{Impl::kNoLo, Impl::kNoHi, Impl::kNoLo, Impl::kNoHi};
      for (std::uint32_t v = cf[col]; v < cf[col + 1]; ++v) {
        const std::uint32_t c = vc[v];
        const HeightPlane& hp = planes[c];
        // Distances relative to the voxel centroid keep float precision far from the origin.
        const float cosf = cosines[c];
        const float x0 = vxp[v], y0 = vyp[v];
        const float h0 = static_cast<float>(hp.at(x0, y0));
        const float a = static_cast<float>(hp.a), b = static_cast<float>(hp.b);
        float lo = -dmax, hi = dmax;
        if (band && m.cell_sigma[c] > 0.0) {
          lo = std::max(lo, static_cast<float>(m.cell_mu[c] - band_k * m.cell_sigma[c]));
          hi = std::min(hi, static_cast<float>(m.cell_mu[c] + band_k * m.cell_sigma[c]));
        }
        std::uint32_t g = 0;
        for (std::uint32_t k = vs[v]; k < vs[v + 1]; ++k) {
          const float d = (z_in[k] - h0 - a * (x_in[k] - x0) - b * (y_in[k] - y0)) * cosf;
          const bool is_ground = (d > lo) & (d < hi);
          gr[k] = is_ground;
          g += is_ground;
        }
        vg[v] = g;
        const std::int32_t iz = static_cast<std::int32_t>(vk[v] & mz);
        if (g != 0) {
          r.glo = std::min(r.glo, iz);
          r.ghi = iz;
        }
        if (g != vs[v + 1] - vs[v]) {
          r.nlo = std::min(r.nlo, iz);
          r.nhi = iz;
        }
      }
      cr[col] = r;
    }
  }
  st.stage_ms.emplace_back("classify", msSince(t0));

  // ---- 8. final 26-neighbourhood majority vote per voxel (point-weighted)
  t0 = Clock::now();
  if (p.majority_vote && have_plane) m.vote();
  st.stage_ms.emplace_back("vote", msSince(t0));

  // Labels back to input order: sorted position -> slot (low word of a packed key, or `order`)
  // -> input index (identity when every point is valid).
  std::size_t ground_count = 0;
  const std::uint64_t* keys = m.keys.data();
  const std::uint32_t* ord = m.order.data();
  const std::uint32_t* idx = m.point_index.data();
  const std::uint8_t* gr = m.ground.data();
  std::uint8_t* out = labels->data();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t slot = m.packed ? static_cast<std::uint32_t>(keys[i]) : ord[i];
    out[m.all_valid ? slot : idx[slot]] = gr[i];
    ground_count += gr[i];
  }
  st.ground_points = ground_count;
  st.total_ms = msSince(t_start);
}

}  // namespace ground_filter
