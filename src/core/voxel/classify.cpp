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
  VoxelRef* ref;
  std::uint8_t* labels;          // per input point
  std::uint32_t* const* counts;  // ground points per voxel, one array per thread
  int count_arrays;              // threads
  std::uint32_t* voxel_ground;   // = counts[0]; the sum of all after columnRanges()
  ZRange* col_range;
  std::uint8_t* col_mask;
  std::uint64_t mask_z;
  float dmax;
};

// Per voxel of columns [c0, c1): the plane height at its centroid (distances relative to it keep
// float precision far from the origin), its centroid's x y and its cell, in one record; clears
// the voxels' ground counts of every thread.
void voxelHeights(const Job& job, std::size_t c0, std::size_t c1) {
  const std::uint32_t* const vcell = job.vcell;
  const float* const vx = job.vx;
  const float* const vy = job.vy;
  const HeightPlane* const planes = job.planes;
  VoxelRef* const ref = job.ref;
  const std::uint32_t v0 = job.col_first[c0], v1 = job.col_first[c1];
  for (std::uint32_t v = v0; v < v1; ++v) {
    const std::uint32_t c = vcell[v];
    ref[v] = VoxelRef{static_cast<float>(planes[c].at(vx[v], vy[v])), vx[v], vy[v], c};
  }
  for (int t = 0; t < job.count_arrays; ++t) {
    std::fill(job.counts[t] + v0, job.counts[t] + v1, 0u);
  }
}

// Labels the valid points of slots [s0, s1) in input order, straight from the x y z v vectors
// (no sorted copies, no way back to input order), and counts the ground points per voxel into
// `counts` (this thread's array). The points' voxels are far apart: their records are
// prefetched a few points ahead.
// Every field is copied to a local first: the byte stores of the labels may alias anything in
// memory, locals not.
template <bool kBand, bool kAllValid>
void classifyPointsT(const Job& job, std::uint32_t* counts, std::size_t s0, std::size_t s1) {
  const std::uint32_t* const pidx = job.point_index;
  const float* const pts = job.pts;
  const CellCoef* const coef = job.coef;
  const VoxelRef* const ref = job.ref;
  std::uint8_t* const labels = job.labels;
  const float dmax = job.dmax;
  constexpr std::size_t kAhead = 16;
  for (std::size_t s = s0; s < s1; ++s) {
    if (s + kAhead < s1) {
      const std::size_t ia = kAllValid ? s + kAhead : pidx[s + kAhead];
      std::uint32_t va;
      std::memcpy(&va, pts + 4 * ia + 3, sizeof va);
      __builtin_prefetch(ref + va);
      __builtin_prefetch(counts + va, 1);
    }
    const std::size_t i = kAllValid ? s : pidx[s];
    const float* p = pts + 4 * i;
    std::uint32_t v;
    std::memcpy(&v, p + 3, sizeof v);
    const VoxelRef r = ref[v];
    const CellCoef& cc = coef[r.cell];
    const float d = (p[2] - r.h0 - cc.a * (p[0] - r.x) - cc.b * (p[1] - r.y)) * cc.cos;
    const float lo = kBand ? cc.lo : -dmax, hi = kBand ? cc.hi : dmax;
    const std::uint32_t is_ground = (d > lo) & (d < hi);
    labels[i] = static_cast<std::uint8_t>(is_ground);
    counts[v] += is_ground;
  }
}

void classifyPoints(const Job& job, int t, std::size_t s0, std::size_t s1) {
  using Fn = void (*)(const Job&, std::uint32_t*, std::size_t, std::size_t);
  static const Fn kFn[2][2] = {{classifyPointsT<false, false>, classifyPointsT<false, true>},
                               {classifyPointsT<true, false>, classifyPointsT<true, true>}};
  kFn[job.band][job.all_valid](job, job.counts[t], s0, s1);  // [band][all valid]
}

// z ranges of the voxels with ground / non-ground points and label mask of columns [c0, c1), in
// one flat pass over the voxels without a branch on the data (columns hold 1-2 voxels on
// average: a loop per column mispredicts its exit). The column's entry is rewritten at each of
// its voxels; the counter moves when the next column starts.
void columnRanges(const Job& job, std::size_t c0, std::size_t c1) {
  const std::uint32_t* const vs = job.vstart;
  const std::uint64_t* const vkey = job.vkey;
  const std::uint32_t* const cf = job.col_first;
  std::uint32_t* const voxel_ground = job.voxel_ground;
  const std::uint32_t* const more = job.count_arrays > 1 ? job.counts[1] : nullptr;
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
    std::uint32_t gcount = voxel_ground[v];
    if (more) {  // several threads counted (integer sums: the same for any split)
      for (int t = 1; t < job.count_arrays; ++t) gcount += job.counts[t][v];
      voxel_ground[v] = gcount;
    }
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
  ref_.resize(nv);
  const std::size_t ncol = g.columns();
  const int nt = threads > 1 && n >= kParallelMinPoints ? threads : 1;
  // Ground counts per voxel: voxel_ground for thread 0, one more array per further thread.
  more_counts_.resize(static_cast<std::size_t>(nt - 1));
  count_ptrs_.resize(static_cast<std::size_t>(nt));
  count_ptrs_[0] = voxel_ground.data();
  for (int t = 1; t < nt; ++t) {
    more_counts_[t - 1].resize(nv);
    count_ptrs_[t] = more_counts_[t - 1].data();
  }
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
  job.ref = ref_.data();
  job.labels = labels;
  job.counts = count_ptrs_.data();
  job.count_arrays = nt;
  job.voxel_ground = voxel_ground.data();
  job.col_range = col_range.data();
  job.col_mask = col_mask.data();
  job.mask_z = g.mask_z;
  job.dmax = dmax;
  if (nt == 1) {
    voxelHeights(job, 0, ncol);
    classifyPoints(job, 0, 0, n);
    columnRanges(job, 0, ncol);
    return;
  }
  // Several threads: voxel records (chunks of columns), labels and per-thread ground counts
  // (chunks of the input), then the counts summed and the z ranges (chunks of columns). The
  // labels of a chunk depend on its range only, the counts are integer sums.
  const int nch = 4 * nt;
  pool->run(nt, nch, [&](int, int c) { voxelHeights(job, ncol * c / nch, ncol * (c + 1) / nch); });
  pool->run(nt, nch, [&](int t, int c) { classifyPoints(job, t, n * c / nch, n * (c + 1) / nch); });
  pool->run(nt, nch, [&](int, int c) { columnRanges(job, ncol * c / nch, ncol * (c + 1) / nch); });
}

}  // namespace voxel
}  // namespace ground_filter
