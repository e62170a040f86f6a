#include "voxel/classify.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace ground_filter {
namespace voxel {

namespace {

// What the classification passes need, by value (the label stores, bytes, may alias anything
// else).
struct Job {
  const std::uint32_t *vstart, *vcell;
  const std::uint64_t* vkey;
  const std::uint32_t* col_first;
  VoxelGrid::InputIndex at;  // sorted position -> input index
  const float* pts;          // x y z v per input point
  const float *vx, *vy;
  const HeightPlane* planes;
  const CellCoef* coef;
  bool band;
  float* h0;
  std::uint8_t* labels;  // per input point
  std::uint32_t* voxel_ground;
  ZRange* col_range;
  std::uint8_t* col_mask;
  std::uint64_t mask_z;
  float dmax;
};

// Plane height at each voxel centroid of columns [c0, c1) (distances relative to it keep float
// precision far from the origin); clears the voxels' ground counts.
void voxelHeights(const Job& job, std::size_t c0, std::size_t c1) {
  const std::uint32_t* const vcell = job.vcell;
  const float* const vx = job.vx;
  const float* const vy = job.vy;
  const HeightPlane* const planes = job.planes;
  float* const h0v = job.h0;
  std::uint32_t* const voxel_ground = job.voxel_ground;
  const std::uint32_t v0 = job.col_first[c0], v1 = job.col_first[c1];
  for (std::uint32_t v = v0; v < v1; ++v) {
    h0v[v] = static_cast<float>(planes[vcell[v]].at(vx[v], vy[v]));
    voxel_ground[v] = 0;
  }
}

// Labels the points of columns [c0, c1) in key order (the voxel values are read in order), their
// coordinates and voxel read from the input-order x y z v vectors through the sort words (as
// build() gathers them, with a prefetch well ahead), each label written straight to its input
// position: no sorted coordinate copies, no way back to input order. Counts ground per voxel.
// Every field is copied to a local first: the byte stores of the labels may alias anything in
// memory, locals not.
template <bool kBand, bool kPacked, bool kAllValid>
void classifyPointsT(const Job& job, std::size_t c0, std::size_t c1) {
  const std::uint64_t* const keys = job.at.keys;
  const std::uint32_t* const order = job.at.order;
  const std::uint32_t* const pidx = job.at.point_index;
  const std::uint64_t slot_mask = job.at.slot_mask;
  const std::uint32_t* const vcell = job.vcell;
  const float* const pts = job.pts;
  const float* const vx = job.vx;
  const float* const vy = job.vy;
  const CellCoef* const coef = job.coef;
  const float* const h0v = job.h0;
  std::uint8_t* const labels = job.labels;
  std::uint32_t* const voxel_ground = job.voxel_ground;
  const float dmax = job.dmax;
  auto inputAt = [&](std::size_t k) -> std::size_t {
    const std::uint32_t slot = kPacked ? static_cast<std::uint32_t>(keys[k] & slot_mask) : order[k];
    return kAllValid ? slot : pidx[slot];
  };
  const std::size_t k0 = job.vstart[job.col_first[c0]], k1 = job.vstart[job.col_first[c1]];
  constexpr std::size_t kAhead = 48;  // as build()'s gather
  for (std::size_t k = k0; k < k1; ++k) {
    if (k + kAhead < k1) __builtin_prefetch(pts + 4 * inputAt(k + kAhead));
    const std::size_t i = inputAt(k);
    const float* p = pts + 4 * i;
    std::uint32_t v;
    std::memcpy(&v, p + 3, sizeof v);
    const CellCoef& cc = coef[vcell[v]];
    const float d = (p[2] - h0v[v] - cc.a * (p[0] - vx[v]) - cc.b * (p[1] - vy[v])) * cc.cos;
    const float lo = kBand ? cc.lo : -dmax, hi = kBand ? cc.hi : dmax;
    const std::uint32_t is_ground = (d > lo) & (d < hi);
    labels[i] = static_cast<std::uint8_t>(is_ground);
    voxel_ground[v] += is_ground;
  }
}

void classifyPoints(const Job& job, std::size_t c0, std::size_t c1) {
  using Fn = void (*)(const Job&, std::size_t, std::size_t);
  static const Fn kFn[2][2][2] = {
      {{classifyPointsT<false, false, false>, classifyPointsT<false, false, true>},
       {classifyPointsT<false, true, false>, classifyPointsT<false, true, true>}},
      {{classifyPointsT<true, false, false>, classifyPointsT<true, false, true>},
       {classifyPointsT<true, true, false>, classifyPointsT<true, true, true>}}};
  kFn[job.band][job.at.packed][job.at.all_valid](job, c0, c1);  // [band][packed][all valid]
}

// z ranges of the voxels with ground / non-ground points and label mask of columns [c0, c1), in
// one flat pass over the voxels without a branch on the data (columns hold 1-2 voxels on
// average: a loop per column mispredicts its exit). The column's entry is rewritten at each of
// its voxels; the counter moves when the next column starts.
void columnRanges(const Job& job, std::size_t c0, std::size_t c1) {
  const std::uint32_t* const vs = job.vstart;
  const std::uint64_t* const vkey = job.vkey;
  const std::uint32_t* const cf = job.col_first;
  const std::uint32_t* const voxel_ground = job.voxel_ground;
  ZRange* const col_range = job.col_range;
  std::uint8_t* const col_mask = job.col_mask;
  const std::uint64_t mz = job.mask_z;
  const std::uint32_t v0 = cf[c0], v1 = cf[c1];
  std::size_t col = c0;
  ZRange r = kEmptyRange;
  for (std::uint32_t v = v0; v < v1; ++v) {
    const bool next = v == cf[col + 1];
    col += next;
    r.glo = next ? kNoLo : r.glo;
    r.ghi = next ? kNoHi : r.ghi;
    r.nlo = next ? kNoLo : r.nlo;
    r.nhi = next ? kNoHi : r.nhi;
    const std::uint32_t gcount = voxel_ground[v];
    const std::int32_t iz = static_cast<std::int32_t>(vkey[v] & mz);
    const bool has_g = gcount != 0, has_n = gcount != vs[v + 1] - vs[v];
    r.glo = std::min(r.glo, has_g ? iz : kNoLo);
    r.ghi = has_g ? iz : r.ghi;
    r.nlo = std::min(r.nlo, has_n ? iz : kNoLo);
    r.nhi = has_n ? iz : r.nhi;
    col_range[col] = r;
    col_mask[col] = static_cast<std::uint8_t>((r.ghi != kNoHi ? 1 : 0) | (r.nhi != kNoHi ? 2 : 0));
  }
}

}  // namespace

void Classifier::bandStats(const VoxelGroundFilterParams& p, const VoxelGrid& g, std::size_t nc,
                           const GroundModel& model, const Segmenter& segs, std::int64_t best) {
  // Mean and std of the signed distances of the points that shaped each plane: the largest
  // segment (global plane) or the cell's seeds within plane_distance of its plane.
  mu_.assign(nc, 0.0);
  sigma_.assign(nc, 0.0);
  count_.assign(nc, 0);
  auto addVoxel = [&](std::uint32_t v) {
    const std::uint32_t c = g.vcell[v];
    const HeightPlane& hp = model.plane(c);
    const double cosf = model.cosine(c);
    for (std::uint32_t k = g.vstart[v]; k < g.vstart[v + 1]; ++k) {
      const float* pt = g.pointAt(k);
      const double d = (pt[2] - hp.at(pt[0], pt[1])) * cosf;
      mu_[c] += d;
      sigma_[c] += d * d;
      ++count_[c];
    }
  };
  if (p.local_planes) {
    for (std::size_t v = 0; v < g.voxels(); ++v) {
      if (!(g.vflags[v] & kSeed)) continue;
      const HeightPlane& hp = model.plane(g.vcell[v]);
      if (std::abs(g.vz[v] - hp.at(g.vx[v], g.vy[v])) < p.plane_distance) {
        addVoxel(static_cast<std::uint32_t>(v));
      }
    }
  } else {
    for (std::size_t i = 0; i < g.flat.size(); ++i) {
      if (segs.segmentOf(i) == static_cast<std::uint32_t>(best)) addVoxel(g.flat[i]);
    }
  }
  for (std::size_t c = 0; c < nc; ++c) {
    const double k = static_cast<double>(count_[c]);
    const double mu = k > 0 ? mu_[c] / k : 0.0;
    sigma_[c] = k > 1 ? std::sqrt(std::max(0.0, sigma_[c] / k - mu * mu)) : 0.0;
    mu_[c] = mu;
  }
}

void Classifier::run(const VoxelGroundFilterParams& p, const VoxelGrid& g, const CellGrid& cells,
                     const GroundModel& model, const Segmenter& segs, std::int64_t best,
                     int threads, WorkerPool* pool, std::uint8_t* labels) {
  const std::size_t n = g.points();
  const std::size_t nv = g.voxels();
  const std::size_t nc = p.local_planes ? cells.count() : 1;
  const bool band = p.std_filter;
  if (band) bandStats(p, g, nc, model, segs, best);
  voxel_ground.resize(nv);
  col_range.resize(g.columns() + 1);  // + an empty sentinel column (the vote's "no column")
  col_mask.resize(g.columns() + 1);
  col_range[g.columns()] = kEmptyRange;
  col_mask[g.columns()] = 0;
  // Per cell: slope and cosine as the per-point test uses them, and the test's band.
  coef_.resize(nc);
  const float dmax = static_cast<float>(p.plane_distance);
  for (std::size_t c = 0; c < nc; ++c) {
    if (p.local_planes && !cells.used[c]) continue;
    const HeightPlane& hp = model.plane(c);
    CellCoef& cc = coef_[c];
    cc.a = static_cast<float>(hp.a);
    cc.b = static_cast<float>(hp.b);
    cc.cos = model.cosine(c);
    cc.lo = -dmax;
    cc.hi = dmax;
    if (band && sigma_[c] > 0.0) {
      cc.lo = std::max(cc.lo, static_cast<float>(mu_[c] - p.std_multiplier * sigma_[c]));
      cc.hi = std::min(cc.hi, static_cast<float>(mu_[c] + p.std_multiplier * sigma_[c]));
    }
  }
  h0_.resize(nv);
  Job job;
  job.vstart = g.vstart.data();
  job.vcell = g.vcell.data();
  job.vkey = g.vkey.data();
  job.col_first = g.col_first.data();
  job.at = g.inputIndex();
  job.pts = g.pts;
  job.vx = g.vx.data();
  job.vy = g.vy.data();
  job.planes = model.planes();
  job.coef = coef_.data();
  job.band = band;
  job.h0 = h0_.data();
  job.labels = labels;
  job.voxel_ground = voxel_ground.data();
  job.col_range = col_range.data();
  job.col_mask = col_mask.data();
  job.mask_z = g.mask_z;
  job.dmax = dmax;
  // Column by column (the vote wants each column's z range of voxels with ground and with
  // non-ground points); a chunk's results depend on its columns only.
  const std::size_t ncol = g.columns();
  const int nt = threads > 1 && n >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;
  pool->run(nt, nch, [&](int, int c) {
    const std::size_t c0 = ncol * c / nch, c1 = ncol * (c + 1) / nch;
    voxelHeights(job, c0, c1);
    classifyPoints(job, c0, c1);
    columnRanges(job, c0, c1);
  });
}

}  // namespace voxel
}  // namespace ground_filter
