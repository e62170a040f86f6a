#include "voxel/segments.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

#include "common/plane_fit.h"

namespace ground_filter {
namespace voxel {

namespace {

// A start segment "lies below the sensor" where its points' mean height is at most this far
// above the sensor [m]: the ground a sensor stands on lies below it, or a little above where it
// rises or the origin sits below the sensor (a frame on its mount); the undersides of crowns
// and ceilings lie higher. Sweeps: 0-0.5 m in sensor frames, 0.5-1 m in base frames.
constexpr double kAboveSensor = 0.5;
// A sensor mounted high (4 m and more: a mast, a roadside pole, a truck's cab) scans the ground
// in rings too far apart to join: the ground falls into one small segment per ring arc, and a
// roof or a crown's top below the sensor outgrows each of them. The ground is the surface that
// most of the flat voxels around the sensor lie at, so a candidate's support is the flat voxels
// within kSupportRadius of the sensor and kSupportBand of its mean height, and the start segment
// is the largest candidate with at least kSupportShare of the best support [m, m, share].
constexpr double kSupportRadius = 40.0;
constexpr double kSupportBand = 0.3;
constexpr double kSupportShare = 0.75;
// A sensor above the ground meets it first with its steepest lines of sight: of the flat voxels
// within kSupportRadius, the kSteepShare it sees steepest down lie mostly where its lowest beams
// meet the ground. Where those lines point kSteepMinDeg or more down (a sensor above the ground,
// not a frame's origin on it), a candidate lying more than kOverSteep above their median height
// is a crown or a roof over ground seen farther out (a 32-beam sensor 3.5-5 m up whose lowest
// beam, -10 deg, meets the ground 20-28 m out): the candidates that do not come first [share,
// deg, m]. Plateaus on generated narrow sensors 3-5 m up and 64 beams 7 m up:
// docs/voxel_method.md.
constexpr double kSteepShare = 0.2;
constexpr double kSteepMinDeg = 5.0;
constexpr double kOverSteep = 1.75;
// Candidates for the start segment: the largest segments (by voxels, then points). A sparse
// sensor's ground falls into many arcs of 4-10 voxels each, below dozens of larger pieces of
// crowns, walls and car tops.
constexpr int kCandidates = 64;

// The median height of the flat voxels that the sensor sees steepest down (kSteepShare of
// `steep`: pairs of the line of sight's slope and the voxel's height, reordered here) into *z,
// where those lines point kSteepMinDeg or more down; false otherwise.
bool steepestLevel(std::vector<std::pair<float, float>>* steep, double* z) {
  if (steep->empty()) return false;
  const std::size_t k = static_cast<std::size_t>(kSteepShare * static_cast<double>(steep->size()));
  const auto first = steep->begin(), last = first + static_cast<std::ptrdiff_t>(k + 1);
  const auto mid = first + static_cast<std::ptrdiff_t>((k + 1) / 2);
  std::nth_element(first, first + static_cast<std::ptrdiff_t>(k), steep->end());
  std::nth_element(first, mid, last);  // the median slope of the steepest
  if (mid->first > -std::tan(kSteepMinDeg * M_PI / 180.0)) return false;
  std::nth_element(first, mid, last,
                   [](const std::pair<float, float>& a, const std::pair<float, float>& b) {
                     return a.second < b.second;
                   });
  *z = mid->second;
  return true;
}

// Raises the candidates of level `need` whose mean height lies at most kOverSteep above
// `steep_z` (steepestLevel()) by one; returns the level to choose from.
std::uint8_t raiseBelowSteep(double steep_z, int ncand, const double* mean_z, std::uint8_t need,
                             std::uint8_t* qualifies) {
  bool any = false;
  for (int q = 0; q < ncand; ++q) {
    if (qualifies[q] == need && mean_z[q] <= steep_z + kOverSteep) {
      qualifies[q] = static_cast<std::uint8_t>(need + 1);
      any = true;
    }
  }
  return static_cast<std::uint8_t>(need + (any ? 1 : 0));
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

}  // namespace

void Segmenter::run(const VoxelGroundFilterParams& p, VoxelGrid* g, SegmentResult* out) {
  Buffer<std::uint32_t>& flat = g->flat;
  // ---- height filter (paper, global plane only): flat voxels higher than the mean flat-voxel
  // height + margin are not ground seeds. The local model has its own, local, windows.
  if (!p.local_planes && !flat.empty()) {
    double flat_z_sum = 0.0;
    for (std::uint32_t v : flat) flat_z_sum += g->vz[v];
    const double cut = flat_z_sum / flat.size() + p.height_margin;
    std::size_t k = 0;
    for (std::uint32_t v : flat) {
      if (g->vz[v] < cut) flat[k++] = v;
    }
    flat.resize(k);
  }
  // ---- region growing over the flat voxels (26-adjacency) as union-find: each flat voxel is
  // joined with the flat voxels among its 13 neighbours with smaller keys: row x - 1 (columns
  // y - 1 .. y + 1), column y - 1 of its own row, and the voxel below it. Rows of flat-column ids
  // (two buffers, x parity) replace any search.
  const std::size_t nf = flat.size();
  out->segment.resize(nf);
  std::uint32_t* u = out->segment.data();
  for (std::size_t i = 0; i < nf; ++i) u[i] = static_cast<std::uint32_t>(i);
  const std::uint32_t* fl = flat.data();
  const std::uint64_t* vk = g->vkey.data();
  const std::size_t stride = g->ny + 2;
  rows_.assign(2 * stride, -1);
  std::int32_t* rows = rows_.data();
  std::array<std::int64_t, 2> held_x = {-1, -1};
  std::array<std::size_t, 2> held_b{}, held_e{};  // flat index range of the row a buffer holds
  const int sy_ = g->shift_y;
  const std::uint64_t my = g->mask_y, mz = g->mask_z;
  const bool one_per_column = p.local_planes;  // see Voxelizer::build()
  std::size_t i = 0;
  while (i < nf) {
    const std::uint64_t x = vk[fl[i]] >> g->shift_x;
    std::size_t e = i;
    while (e < nf && (vk[fl[e]] >> g->shift_x) == x) ++e;
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
    if (one_per_column) {
      // At most one flat voxel a column (the local model's seeds are the lowest voxel of their
      // column): a neighbour column holds one candidate, joined when within one z step.
      for (std::size_t a = i; a < e; ++a) {
        const std::uint64_t key = vk[fl[a]];
        const std::int64_t y = static_cast<std::int64_t>((key >> sy_) & my);
        const std::int64_t z = static_cast<std::int64_t>(key & mz);
        const std::int32_t nbs[4] = {cur[y - 1], has_prev ? prev[y - 1] : -1,
                                     has_prev ? prev[y] : -1, has_prev ? prev[y + 1] : -1};
        for (std::int32_t f : nbs) {
          const std::size_t b = f < 0 ? a : static_cast<std::size_t>(f);  // a: never joined
          const std::int64_t dz = static_cast<std::int64_t>(vk[fl[b]] & mz) - z;
          if ((f >= 0) & (dz >= -1) & (dz <= 1)) {
            unite(u, static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
          }
        }
      }
      i = e;
      continue;
    }
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
  seg_voxels_.assign(nf, 0);
  seg_points_.assign(nf, 0);
  for (std::size_t j = 0; j < nf; ++j) {
    const std::uint32_t r = findRoot(u, static_cast<std::uint32_t>(j));
    u[j] = r;  // flattened: segment[j] is the segment id (its root) from here on
    ++seg_voxels_[r];
    seg_points_[r] += g->pointsIn(fl[j]);
  }
  std::int64_t best = -1;
  for (std::size_t j = 0; j < nf; ++j) {
    if (u[j] != j) continue;
    if (best < 0 || seg_voxels_[j] > seg_voxels_[best] ||
        (seg_voxels_[j] == seg_voxels_[best] && seg_points_[j] > seg_points_[best])) {
      best = static_cast<std::int64_t>(j);
    }
  }
  out->best = best;
}

void Segmenter::scanNearSensor(const VoxelGrid& g, const float* sensor, double bin) {
  const double sx = sensor[0] - g.min[0], sy = sensor[1] - g.min[1], sz = sensor[2] - g.min[2];
  hist_.clear();
  steep_.clear();
  for (std::uint32_t v : g.flat) {
    const double dx = g.vx[v] - sx, dy = g.vy[v] - sy;
    if (dx * dx + dy * dy > kSupportRadius * kSupportRadius) continue;
    // Heights are relative to the grid's min corner: bin >= 0.
    const std::size_t b = static_cast<std::size_t>(std::max(0.0, g.vz[v] / bin));
    if (b >= hist_.size()) hist_.resize(b + 1, 0);
    ++hist_[b];
    steep_.emplace_back(static_cast<float>((g.vz[v] - sz) / std::sqrt(dx * dx + dy * dy + 1e-6)),
                        g.vz[v]);
  }
}

void Segmenter::globalPlane(const VoxelGroundFilterParams& p, const VoxelGrid& g,
                            const float* sensor, SegmentResult* seg) {
  seg->have_plane = seg->best >= 0;
  if (!seg->have_plane) return;
  const std::uint32_t* uf = seg->segment.data();
  HeightPlane* gp = &seg->plane;
  // The plane of the largest segment that is not steeper than max_slope_deg: the largest one can
  // be a wall scanned line by line (its flat voxels stack up), see the docs.
  std::array<std::uint32_t, kCandidates> cand{};
  int ncand = 0;
  auto better = [&](std::uint32_t a, std::uint32_t b) {
    return seg_voxels_[a] != seg_voxels_[b] ? seg_voxels_[a] > seg_voxels_[b]
                                            : seg_points_[a] > seg_points_[b];
  };
  const std::size_t nf = g.flat.size();
  for (std::size_t j = 0; j < nf; ++j) {  // the largest segments, by voxels then points
    if (uf[j] != j) continue;
    int pos = ncand;
    while (pos > 0 && better(static_cast<std::uint32_t>(j), cand[pos - 1])) --pos;
    if (pos >= kCandidates) continue;
    for (int q = std::min(ncand, kCandidates - 1); q > pos; --q) cand[q] = cand[q - 1];
    cand[pos] = static_cast<std::uint32_t>(j);
    ncand = std::min(ncand + 1, kCandidates);
  }
  std::array<PlaneAccumulator, kCandidates> acc;
  std::array<double, kCandidates> zsum{}, zzsum{}, cnt{};
  rank_.assign(nf, -1);  // a lookup instead of a search of the candidates per flat voxel
  for (int q = 0; q < ncand; ++q) rank_[cand[q]] = static_cast<std::int8_t>(q);
  for (std::size_t j = 0; j < nf; ++j) {
    const int q = rank_[uf[j]];
    if (q < 0) continue;
    const std::uint32_t v = g.flat[j];
    for (std::uint32_t k = g.vstart[v]; k < g.vstart[v + 1]; ++k) {
      const float* pt = g.xyz(k);
      acc[q].add(pt[0], pt[1], pt[2]);
      zsum[q] += pt[2];
      zzsum[q] += static_cast<double>(pt[2]) * pt[2];
      cnt[q] += 1.0;
    }
  }
  const double min_nz = std::cos(p.max_slope_deg * M_PI / 180.0);
  // A sensor's own scan: the largest segment that lies below the sensor (kAboveSensor) and whose
  // plane passes below it; else the largest whose plane passes below it; else (none does, or no
  // sensor at the origin) the largest. A sparse sensor's rings fall apart into one segment each,
  // and the underside of a tree crown, a ceiling or a roof can outgrow them all; a crown's tilted
  // plane can pass below the sensor all the same, while its points stay above it. Among the
  // segments that qualify, the best supported wins over a larger one (kSupportShare); those not
  // above the ground that the sensor's steepest lines of sight meet come first (kOverSteep).
  std::array<HeightPlane, kCandidates> planes;
  std::array<double, kCandidates> mean_z{};
  // 1: passes below, 2: lies below too, 3: and not above the steepest level (steepestLevel())
  std::array<std::uint8_t, kCandidates> qualifies{};
  int chosen = -1;  // the largest with a fitted plane, unless a sensor picks another below
  for (int q = 0; q < ncand; ++q) {
    Plane plane;
    HeightPlane& hp = planes[q];
    mean_z[q] = zsum[q] / cnt[q];
    if (acc[q].fit(&plane) && plane.normal.z() >= min_nz) {
      hp.a = -plane.normal.x() / plane.normal.z();
      hp.b = -plane.normal.y() / plane.normal.z();
      hp.c = -plane.d / plane.normal.z();
      if (chosen < 0) {
        chosen = q;
        if (!sensor) break;
      }
    } else if (sensor && std::sqrt(std::max(0.0, zzsum[q] / cnt[q] - mean_z[q] * mean_z[q])) <=
                             kSupportBand) {
      // One ring's arc: too narrow for a slope, level within the band: a level plane.
      hp = HeightPlane();
      hp.c = mean_z[q];
    } else {
      continue;
    }
    const double sz = sensor[2] - g.min[2];  // the plane's frame: relative to the grid's min
    if (hp.at(sensor[0] - g.min[0], sensor[1] - g.min[1]) >= sz) continue;
    qualifies[q] = mean_z[q] < sz + kAboveSensor ? 2 : 1;
  }
  if (sensor) {
    // Support: one pass over the flat voxels near the sensor, a histogram of their heights.
    std::uint8_t need =
        *std::max_element(qualifies.begin(), qualifies.begin() + std::max(ncand, 1));
    if (need > 0) {
      const double bin = kSupportBand / 3.0;
      scanNearSensor(g, sensor, bin);
      const long nbins = static_cast<long>(hist_.size());
      std::array<std::uint32_t, kCandidates> support{};
      for (int q = 0; q < ncand; ++q) {
        if (qualifies[q] != need) continue;
        const long centre = static_cast<long>(std::floor(mean_z[q] / bin));
        for (long b = std::max(0L, centre - 3); b <= std::min(nbins - 1, centre + 3); ++b) {
          support[q] += hist_[static_cast<std::size_t>(b)];
        }
      }
      // Those not above the ground the sensor's steepest lines of sight meet: a level of their
      // own (kOverSteep).
      double steep_z = 0.0;
      if (steepestLevel(&steep_, &steep_z)) {
        need = raiseBelowSteep(steep_z, ncand, mean_z.data(), need, qualifies.data());
      }
      std::uint32_t top = 0;
      for (int q = 0; q < ncand; ++q) {
        if (qualifies[q] == need) top = std::max(top, support[q]);
      }
      // The best supported qualifies itself, so one is always found.
      chosen = -1;
      for (int q = 0; q < ncand && chosen < 0; ++q) {
        if (qualifies[q] == need && support[q] >= kSupportShare * top) chosen = q;
      }
    }
  }
  if (chosen >= 0) {
    seg->best = cand[chosen];
    *gp = planes[chosen];
    return;
  }
  *gp = HeightPlane();
  gp->c = zsum[0] / cnt[0];  // no sub-horizontal plane (one scan line): level, through the largest
}

}  // namespace voxel
}  // namespace ground_filter
