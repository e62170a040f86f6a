#include "voxel/classify.h"

#include <algorithm>
#include <cmath>

#include "common/prefetch.h"

namespace ground_filter {
namespace voxel {

namespace {

// What classifyColumns() needs, by value (the label stores, bytes, may alias anything else).
struct Job {
  const std::uint32_t *vstart, *vcell;
  const std::uint64_t* vkey;
  const std::uint32_t* col_first;
  const std::uint32_t* pvox;
  const float *xyz, *vx, *vy;  // x y z per point, centroid x and y per voxel
  const HeightPlane* planes;
  const CellCoef* coef;
  bool band;
  float* h0;
  std::uint8_t* ground;
  std::uint32_t* voxel_ground;
  ZRange* col_range;
  std::uint8_t* col_mask;
  std::uint64_t mask_z;
  float dmax;
};

// Labels the points of columns [c0, c1) in three flat passes (voxels, points, columns): voxels
// hold 1-2 points on average, and loops per voxel over its points mispredict their exits.
// Every field is copied to a local first: the byte stores of the labels may alias anything in
// memory, locals not.
template <bool kBand>
void classifyColumnsT(const Job& job, std::size_t c0, std::size_t c1) {
  const std::uint32_t* const vs = job.vstart;
  const std::uint32_t* const vcell = job.vcell;
  const std::uint64_t* const vkey = job.vkey;
  const std::uint32_t* const cf = job.col_first;
  const std::uint32_t* const pvox = job.pvox;
  const float* const pxyz = job.xyz;
  const float* const vx = job.vx;
  const float* const vy = job.vy;
  const HeightPlane* const planes = job.planes;
  const CellCoef* const coef = job.coef;
  float* const h0v = job.h0;
  std::uint8_t* const ground = job.ground;
  std::uint32_t* const voxel_ground = job.voxel_ground;
  ZRange* const col_range = job.col_range;
  std::uint8_t* const col_mask = job.col_mask;
  const std::uint64_t mz = job.mask_z;
  const float dmax = job.dmax;
  // Plane height at each voxel centroid: distances relative to it keep float precision far from
  // the origin.
  const std::uint32_t v0 = cf[c0], v1 = cf[c1];
  for (std::uint32_t v = v0; v < v1; ++v) {
    h0v[v] = static_cast<float>(planes[vcell[v]].at(vx[v], vy[v]));
    voxel_ground[v] = 0;
  }
  const std::uint32_t k1 = vs[v1];
  for (std::uint32_t k = vs[v0]; k < k1; ++k) {
    const std::uint32_t v = pvox[k];
    const CellCoef& cc = coef[vcell[v]];
    const float* pt = pxyz + 3 * static_cast<std::size_t>(k);
    // The 12-byte stride is not prefetched well by this VM's hardware (classify of a 2 M-point
    // TLS scan took 11.6 ms without this line, 6.0 ms with it).
    prefetchAhead(pt, 12 * 64);
    const float d = (pt[2] - h0v[v] - cc.a * (pt[0] - vx[v]) - cc.b * (pt[1] - vy[v])) * cc.cos;
    const float lo = kBand ? cc.lo : -dmax, hi = kBand ? cc.hi : dmax;
    const std::uint32_t is_ground = (d > lo) & (d < hi);
    ground[k] = static_cast<std::uint8_t>(is_ground);
    voxel_ground[v] += is_ground;
  }
  // z ranges per column in one flat pass over the voxels without a branch on the data (columns
  // hold 1-2 voxels on average: a loop per column mispredicts its exit). The column's entry is
  // rewritten at each of its voxels; the counter moves when the next column starts.
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

void classifyColumns(const Job& job, std::size_t c0, std::size_t c1) {
  if (job.band) {
    classifyColumnsT<true>(job, c0, c1);
  } else {
    classifyColumnsT<false>(job, c0, c1);
  }
}

}  // namespace

void Classifier::bandStats(const VoxelGroundFilterParams& p, const VoxelGrid& g, std::size_t nc,
                           const GroundModelResult& model, const SegmentResult& seg) {
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
      const float* pt = g.xyz(k);
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
      if (seg.segment[i] == static_cast<std::uint32_t>(seg.best)) addVoxel(g.flat[i]);
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
                     const GroundModelResult& model, const SegmentResult& seg, int threads,
                     WorkerPool* pool, ClassifyResult* out) {
  std::vector<std::uint8_t>& ground = out->ground;
  std::vector<std::uint32_t>& voxel_ground = out->voxel_ground;
  std::vector<ZRange>& col_range = out->col_range;
  std::vector<std::uint8_t>& col_mask = out->col_mask;
  std::vector<float>& h0 = out->plane_height;
  const std::size_t n = g.points();
  const std::size_t nv = g.voxels();
  const std::size_t nc = p.local_planes ? cells.count() : 1;
  const bool band = p.std_filter;
  if (band) bandStats(p, g, nc, model, seg);
  ground.resize(n);
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
  h0.resize(nv);
  Job job;
  job.vstart = g.vstart.data();
  job.vcell = g.vcell.data();
  job.vkey = g.vkey.data();
  job.col_first = g.col_first.data();
  job.pvox = g.pvox.data();
  job.xyz = g.sxyz.data();
  job.vx = g.vx.data();
  job.vy = g.vy.data();
  job.planes = model.planes.data();
  job.coef = coef_.data();
  job.band = band;
  job.h0 = h0.data();
  job.ground = ground.data();
  job.voxel_ground = voxel_ground.data();
  job.col_range = col_range.data();
  job.col_mask = col_mask.data();
  job.mask_z = g.mask_z;
  job.dmax = dmax;
  // Column by column (the vote wants each column's z range of voxels with ground and with
  // non-ground points).
  const std::size_t ncol = g.columns();
  const int nt = threads > 1 && n >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;
  pool->run(nt, nch,
            [&](int, int c) { classifyColumns(job, ncol * c / nch, ncol * (c + 1) / nch); });
}

}  // namespace voxel
}  // namespace ground_filter
