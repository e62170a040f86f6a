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
  const std::uint32_t* point_index;  // input index per slot (not all valid)
  const float* pts;                  // x y z v per input point
  const float *vx, *vy;
  const HeightPlane* planes;
  const CellCoef* coef;
  bool band, all_valid;
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

// Labels the valid points of slots [s0, s1) in input order, straight from the x y z v vectors
// (no sorted copies, no way back to input order); counts the ground points per voxel when
// kCount (one thread: a voxel's points may lie in several chunks).
// Every field is copied to a local first: the byte stores of the labels may alias anything in
// memory, locals not.
template <bool kBand, bool kAllValid, bool kCount>
void classifyPointsT(const Job& job, std::size_t s0, std::size_t s1) {
  const std::uint32_t* const vcell = job.vcell;
  const std::uint32_t* const pidx = job.point_index;
  const float* const pts = job.pts;
  const float* const vx = job.vx;
  const float* const vy = job.vy;
  const CellCoef* const coef = job.coef;
  const float* const h0v = job.h0;
  std::uint8_t* const labels = job.labels;
  std::uint32_t* const voxel_ground = job.voxel_ground;
  const float dmax = job.dmax;
  for (std::size_t s = s0; s < s1; ++s) {
    const std::size_t i = kAllValid ? s : pidx[s];
    const float* p = pts + 4 * i;
    std::uint32_t v;
    std::memcpy(&v, p + 3, sizeof v);
    const CellCoef& cc = coef[vcell[v]];
    const float d = (p[2] - h0v[v] - cc.a * (p[0] - vx[v]) - cc.b * (p[1] - vy[v])) * cc.cos;
    const float lo = kBand ? cc.lo : -dmax, hi = kBand ? cc.hi : dmax;
    const std::uint32_t is_ground = (d > lo) & (d < hi);
    labels[i] = static_cast<std::uint8_t>(is_ground);
    if (kCount) voxel_ground[v] += is_ground;
  }
}

void classifyPoints(const Job& job, bool count, std::size_t s0, std::size_t s1) {
  using Fn = void (*)(const Job&, std::size_t, std::size_t);
  static const Fn kFn[2][2][2] = {
      {{classifyPointsT<false, false, false>, classifyPointsT<false, false, true>},
       {classifyPointsT<false, true, false>, classifyPointsT<false, true, true>}},
      {{classifyPointsT<true, false, false>, classifyPointsT<true, false, true>},
       {classifyPointsT<true, true, false>, classifyPointsT<true, true, true>}}};
  kFn[job.band][job.all_valid][count](job, s0, s1);  // [band][all valid][count per voxel]
}

// Ground points per voxel of columns [c0, c1) from the labels (several threads: the point pass
// could not count them), the same integers as classifyPointsT<..., true>.
void countGround(const Job& job, const VoxelGrid& g, std::size_t c0, std::size_t c1) {
  const std::uint32_t* const vs = job.vstart;
  const std::uint8_t* const labels = job.labels;
  std::uint32_t* const voxel_ground = job.voxel_ground;
  const VoxelGrid::InputIndex at = g.inputIndex();
  const std::uint32_t v0 = job.col_first[c0], v1 = job.col_first[c1];
  for (std::uint32_t v = v0; v < v1; ++v) {
    std::uint32_t c = 0;
    for (std::uint32_t k = vs[v]; k < vs[v + 1]; ++k) c += labels[at(k)];
    voxel_ground[v] = c;
  }
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
  job.point_index = g.point_index.data();
  job.pts = g.pts;
  job.vx = g.vx.data();
  job.vy = g.vy.data();
  job.planes = model.planes();
  job.coef = coef_.data();
  job.band = band;
  job.all_valid = g.all_valid;
  job.h0 = h0_.data();
  job.labels = labels;
  job.voxel_ground = voxel_ground.data();
  job.col_range = col_range.data();
  job.col_mask = col_mask.data();
  job.mask_z = g.mask_z;
  job.dmax = dmax;
  const std::size_t ncol = g.columns();
  const int nt = threads > 1 && n >= kParallelMinPoints ? threads : 1;
  if (nt == 1) {
    voxelHeights(job, 0, ncol);
    classifyPoints(job, true, 0, n);
    columnRanges(job, 0, ncol);
    return;
  }
  // Several threads: heights per voxel (chunks of columns), labels (chunks of the input), then
  // ground counts and z ranges (chunks of columns). Each chunk's results depend on its range
  // only.
  const int nch = 4 * nt;
  pool->run(nt, nch, [&](int, int c) { voxelHeights(job, ncol * c / nch, ncol * (c + 1) / nch); });
  pool->run(nt, nch,
            [&](int, int c) { classifyPoints(job, false, n * c / nch, n * (c + 1) / nch); });
  pool->run(nt, nch, [&](int, int c) {
    const std::size_t c0 = ncol * c / nch, c1 = ncol * (c + 1) / nch;
    countGround(job, g, c0, c1);
    columnRanges(job, c0, c1);
  });
}

}  // namespace voxel
}  // namespace ground_filter
