#include "voxel/ground_model.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ground_filter {
namespace voxel {

namespace {

// Weight of the prior slope in a cell fit, in points at a cell edge's distance: keeps a cell whose
// seeds are one scan line (collinear) from tilting around it.
constexpr double kSlopePriorWeight = 1.0;
// Cells of the local model farther than this from any cell with points are not grown.
constexpr std::int64_t kReachCells = 4;
// Grade the ground may climb across cells without seeds [m/m]: a prediction carried level over
// such a stretch (between the rings of a sparse sensor) accepts seeds this much higher per
// metre crossed, up to kGapRise. The rings of a 16-beam sensor on a 4-7 % grade lie 4-10 m
// apart and 0.3-0.7 m above the level prediction. 0.03-0.07 one plateau (docs/voxel_method.md,
// "A grade between sparse rings").
constexpr double kGapGrade = 0.05;
// The most the window widens that way [m]: beyond 6 m of gap the widening reached the crowns
// and car tops below a narrow sensor 5 m up (F1 95.5 -> 87.5); 0.2-0.3 keep it and most of the
// grades' gain.
constexpr double kGapRise = 0.3;

}  // namespace

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

void GroundModel::setGlobal(const SegmentResult& seg, GroundModelResult* out) {
  const HeightPlane& gp = seg.plane;
  out->planes.assign(1, gp);
  out->cos.assign(1, static_cast<float>(1.0 / std::sqrt(1.0 + gp.a * gp.a + gp.b * gp.b)));
}

void GroundModel::markReach(const CellGrid& cells) {
  // A box dilation of the cells holding voxels by kReachCells either way, separable: along y
  // (within each row, x major) into near_y_, then along x into reach_. Both are ORs of shifted
  // byte rows without a dependency from one cell to the next, which the compiler vectorises.
  constexpr std::size_t kR = static_cast<std::size_t>(kReachCells);
  const std::size_t ncx = cells.ncx, ncy = cells.ncy;
  near_y_.resize(cells.count());
  reach_.resize(cells.count());
  for (std::size_t x = 0; x < ncx; ++x) {
    const std::uint8_t* u = cells.used.data() + x * ncy;
    std::uint8_t* r = near_y_.data() + x * ncy;
    auto edge = [&](std::size_t y) {  // the window cut by the row's ends
      std::uint8_t v = 0;
      for (std::size_t j = y > kR ? y - kR : 0; j <= std::min(y + kR, ncy - 1); ++j) v |= u[j];
      r[y] = v;
    };
    const std::size_t head = std::min(kR, ncy);
    for (std::size_t y = 0; y < head; ++y) edge(y);
    for (std::size_t y = kR; y + kR < ncy; ++y) {
      std::uint8_t v = 0;
      for (std::size_t j = 0; j <= 2 * kR; ++j) v |= u[y - kR + j];
      r[y] = v;
    }
    for (std::size_t y = std::max(kR, ncy > kR ? ncy - kR : 0); y < ncy; ++y) edge(y);
  }
  for (std::size_t x = 0; x < ncx; ++x) {
    std::uint8_t* r = reach_.data() + x * ncy;
    const std::size_t x0 = x > kR ? x - kR : 0, x1 = std::min(x + kR, ncx - 1);
    std::copy(near_y_.data() + x0 * ncy, near_y_.data() + (x0 + 1) * ncy, r);
    for (std::size_t xx = x0 + 1; xx <= x1; ++xx) {
      const std::uint8_t* n = near_y_.data() + xx * ncy;
      for (std::size_t y = 0; y < ncy; ++y) r[y] |= n[y];
    }
  }
}

std::size_t GroundModel::bucketSeeds(const VoxelGrid& g, std::size_t nc, const SegmentResult& segs,
                                     std::int64_t best) {
  // Seed candidates per cell (CSR, coordinates copied for sequential access); start cell = most
  // voxels of the largest segment.
  // Counts go to start_[c + 2] and the scatter advances start_[c + 1], which ends as the start
  // of cell c + 1: no cursor copy.
  const std::uint32_t* vc = g.vcell.data();
  start_.assign(nc + 2, 0);
  std::uint32_t* const st = start_.data();
  for (std::uint32_t v : g.seeds) ++st[vc[v] + 2];
  for (std::size_t c = 0; c < nc; ++c) st[c + 2] += st[c + 1];
  seeds_.resize(g.seeds.size());
  for (std::uint32_t v : g.seeds) {
    seeds_[st[vc[v] + 1]++] = Seed{g.vx[v], g.vy[v], g.vz[v], static_cast<float>(g.pointsIn(v))};
  }
  start_.pop_back();
  // Voxels of segment `best` per cell, counted only in the cells it touches; ties go to the
  // lowest cell index (as a max_element over every cell would).
  seg_count_.resize(nc);
  std::uint32_t* const seg_in_cell = seg_count_.data();
  const std::uint32_t b = static_cast<std::uint32_t>(best);
  for (std::size_t i = 0; i < g.flat.size(); ++i) {
    if (segs.segment[i] == b) seg_in_cell[vc[g.flat[i]]] = 0;
  }
  std::size_t start = 0;
  std::uint32_t most = 0;
  for (std::size_t i = 0; i < g.flat.size(); ++i) {
    if (segs.segment[i] != b) continue;
    const std::uint32_t c = vc[g.flat[i]];
    const std::uint32_t k = ++seg_in_cell[c];
    if (k > most || (k == most && c < start)) {
      most = k;
      start = c;
    }
  }
  return start;
}

void GroundModel::resetCells(const CellGrid& cells) {
  const std::size_t nc = cells.count();
  const std::uint64_t ncx = cells.ncx, ncy = cells.ncy;
  // Moments and planes are not cleared (96 bytes a cell, most cells empty): nb_ok_ says which
  // cells hold moments this scan, and a plane is read only after it was written, except the
  // final plane of a cell never grown, which is the global plane (grow()).
  nbsum_.resize(nc);
  nb_ok_.assign(nc, 0);
  plane_.resize(nc);
  parent_.resize(nc);
  gap_.resize(nc);
  state_.resize(nc);
  near_q_.assign(nc, 0);
  CellState* state = state_.data();
  // Cells farther than kReachCells from any cell with points are never grown (kDone): they
  // would only carry the prediction across empty space. Data beyond such a stretch are grown
  // again from a new start (nextIsland()). The border is kDone too.
  markReach(cells);
  const std::uint8_t* reach = reach_.data();
  for (std::size_t t = 0; t < nc; ++t) state[t] = reach[t] ? CellState::kNew : CellState::kDone;
  for (std::uint64_t x = 0; x < ncx; ++x) {
    state[x * ncy] = state[x * ncy + ncy - 1] = CellState::kDone;
  }
  for (std::uint64_t y = 0; y < ncy; ++y) {
    state[y] = state[(ncx - 1) * ncy + y] = CellState::kDone;
  }
  queue_.resize(nc + 2);  // one near entry per cell, the start, one store past the end
  queue_far_.resize(nc + 1);
  near_end_ = far_end_ = 0;
}

HeightPlane GroundModel::startPlane(const VoxelGrid& g, const SegmentResult& segs,
                                    std::int64_t best, std::size_t start,
                                    const HeightPlane& gp) const {
  // The largest segment's voxels in the start cell (level slope prior), so a tilted global plane
  // cannot put it off the ground it was chosen for.
  Moments sm;
  for (std::size_t i = 0; i < g.flat.size(); ++i) {
    const std::uint32_t v = g.flat[i];
    if (segs.segment[i] == static_cast<std::uint32_t>(best) && g.vcell[v] == start) {
      sm.add(g.vx[v], g.vy[v], g.vz[v], static_cast<double>(g.pointsIn(v)));
    }
  }
  return sm.w > 0 ? fitHeightPlane(sm, 0.0, 0.0, geo_.lambda) : gp;
}

bool GroundModel::nextIsland(const CellGrid& cells, std::size_t* next, std::uint32_t* cell) {
  // Cells with points not reached (beyond an empty stretch): grow again from the first of them
  // with seeds, predicted level through its lowest seed (the ground is the lowest surface);
  // cells without seeds left over keep the global plane.
  const std::size_t nc = cells.count();
  const std::uint32_t* cst = start_.data();
  std::size_t i = *next;
  while (i < nc && !(cells.used[i] && state_[i] == CellState::kNew && cst[i + 1] > cst[i])) ++i;
  *next = i;
  if (i == nc) return false;
  const std::uint32_t t = static_cast<std::uint32_t>(i);
  float zlow = std::numeric_limits<float>::max();
  for (std::uint32_t k = cst[t]; k < cst[t + 1]; ++k) zlow = std::min(zlow, seeds_[k].z);
  plane_[t] = HeightPlane();
  plane_[t].c = zlow;
  parent_[t] = t;
  state_[t] = CellState::kQueued;
  *cell = t;
  return true;
}

bool GroundModel::fitCell(const VoxelGroundFilterParams& p, std::uint32_t t) {
  // Prediction: the parent's height at this cell's centre (level), refined by the seeds of the
  // finished neighbours (also for empty cells: they pass it on). Seeds: the candidates from
  // height_margin below to seed_window above the prediction (the ground is the lowest surface:
  // lower candidates are safe, higher ones may be objects; kGapGrade more above for each metre
  // the prediction crossed without seeds, at most kGapRise), refit, then those within
  // plane_distance of the refit, refit again.
  const std::uint32_t tx = t / geo_.ncy, ty = t - tx * geo_.ncy;
  const double cx = (tx - 0.5) * geo_.cs;  // the border shifts the cell indices by one
  const double cy = (ty - 0.5) * geo_.cs;
  const std::uint32_t par = parent_[t];
  const std::uint16_t gap = par == t || state_[par] == CellState::kDoneSeeded
                                ? 0
                                : static_cast<std::uint16_t>(std::min(gap_[par] + 1, 65535));
  gap_[t] = gap;
  HeightPlane pred;
  pred.c = plane_[par].at(cx, cy);
  const Moments nb = sumsOf(t);
  if (nb.w > 0) pred = fitHeightPlane(nb, 0.0, 0.0, geo_.lambda);
  HeightPlane cur = pred;
  Moments own;
  const std::uint32_t s0 = start_[t], s1 = start_[t + 1];
  if (s1 > s0) {
    double below = p.height_margin;
    double above = p.seed_window + std::min(kGapRise, kGapGrade * geo_.cs * gap);
    for (int pass = 0; pass < 2; ++pass) {
      own = Moments();
      for (std::uint32_t k = s0; k < s1; ++k) {
        const Seed& sd = seeds_[k];
        const double dz = sd.z - cur.at(sd.x, sd.y);
        if (dz < above && dz > -below) own.add(sd.x, sd.y, sd.z, sd.w);
      }
      if (own.w <= 0) break;
      Moments tot = nb;
      tot.add(own);
      cur = fitHeightPlane(tot, 0.0, 0.0, geo_.lambda);
      below = above = p.plane_distance;
    }
  }
  const bool seeded = own.w > 0 && cur.a * cur.a + cur.b * cur.b <= geo_.max_grad2;
  if (seeded) {
    plane_[t] = cur;
    state_[t] = CellState::kDoneSeeded;
    for (int k = 0; k < 9; ++k) {
      const std::size_t u = static_cast<std::size_t>(t + geo_.nb_off[k]);
      Moments m = sumsOf(u);  // 0 + own in a cell without sums: what a cleared grid gave
      m.add(own);
      nbsum_[u] = m;
      nb_ok_[u] = 1;
    }
  } else {
    plane_[t] = pred;
    state_[t] = CellState::kDone;
  }
  return seeded;
}

void GroundModel::queueNeighbours(std::uint32_t t, bool seeded) {
  // Two FIFO queues: cells next to a cell with accepted seeds first ("near"), the rest after
  // ("far"), so the model grows where there is evidence and crosses empty stretches (the
  // sensor's blind circle, shadows) last, from all sides. A seeded cell queues every unfinished
  // neighbour not already waiting near seeds; an unseeded one only new cells. Written without
  // branches per neighbour (an entry is always stored, and counted when taken): the queues hold
  // at most one entry per cell each (+ the start), see resetCells().
  CellState* state = state_.data();
  std::uint32_t* parent = parent_.data();
  if (seeded) {
    std::uint8_t* near_q = near_q_.data();
    std::uint32_t* q = queue_.data();
    for (int k = 0; k < 9; ++k) {
      const std::size_t u = static_cast<std::size_t>(t + geo_.nb_off[k]);
      const CellState su = state[u];
      const bool take = !finished(su) && !(su == CellState::kQueued && near_q[u]);
      q[near_end_] = static_cast<std::uint32_t>(u);
      near_end_ += take;
      near_q[u] = static_cast<std::uint8_t>(near_q[u] | take);
      state[u] = take ? CellState::kQueued : su;
      parent[u] = take ? t : parent[u];
    }
  } else {
    std::uint32_t* q = queue_far_.data();
    for (int k = 0; k < 9; ++k) {
      const std::size_t u = static_cast<std::size_t>(t + geo_.nb_off[k]);
      const CellState su = state[u];
      const bool take = su == CellState::kNew;
      q[far_end_] = static_cast<std::uint32_t>(u);
      far_end_ += take;
      state[u] = take ? CellState::kQueued : su;
      parent[u] = take ? t : parent[u];
    }
  }
}

void GroundModel::grow(const VoxelGroundFilterParams& p, const VoxelGrid& g, const CellGrid& cells,
                       const SegmentResult& seg, GroundModelResult* out) {
  const HeightPlane& gp = seg.plane;
  const std::int64_t best = seg.best;
  const std::size_t nc = cells.count();
  geo_.cs = static_cast<double>(cells.cell_vox) * p.voxel_size;
  geo_.lambda = kSlopePriorWeight * geo_.cs * geo_.cs;
  const double max_grad = std::tan(p.max_slope_deg * M_PI / 180.0);
  geo_.max_grad2 = max_grad * max_grad;
  geo_.ncy = static_cast<std::uint32_t>(cells.ncy);
  const std::int64_t stride = static_cast<std::int64_t>(cells.ncy);  // includes the border
  const std::int64_t off[9] = {-stride - 1, -stride,    -stride + 1, -1,        0,
                               1,           stride - 1, stride,      stride + 1};
  std::copy(off, off + 9, geo_.nb_off);

  // Growth from the cell holding most of the largest segment, then from every island of cells
  // with seeds it did not reach (the grid's border cells are kDone: 3 x 3 neighbourhoods need
  // no bounds checks).
  const std::size_t start = bucketSeeds(g, nc, seg, best);
  resetCells(cells);
  plane_[start] = startPlane(g, seg, best, start, gp);
  parent_[start] = static_cast<std::uint32_t>(start);
  state_[start] = CellState::kQueued;
  queue_[near_end_++] = static_cast<std::uint32_t>(start);
  std::size_t qn = 0, qf = 0, next_island = 0;
  // The cells are taken in queue order, scattered over a grid of moments larger than L2:
  // prefetch the moments of the cell 4 entries on, where it has some (the others' pages may
  // never have been written: a prefetch there costs a page walk and brings nothing).
  auto prefetchCell = [&](const std::uint32_t* q, std::size_t i, std::size_t end) {
    if (i + 4 < end && nb_ok_[q[i + 4]]) {
      const char* m = reinterpret_cast<const char*>(&nbsum_[q[i + 4]]);
      __builtin_prefetch(m);
      __builtin_prefetch(m + sizeof(Moments) - 1);
    }
  };
  for (;;) {
    std::uint32_t t;
    if (qn < near_end_) {
      prefetchCell(queue_.data(), qn, near_end_);
      t = queue_[qn++];
    } else if (qf < far_end_) {
      prefetchCell(queue_far_.data(), qf, far_end_);
      t = queue_far_[qf++];
    } else if (!nextIsland(cells, &next_island, &t)) {
      break;
    }
    if (finished(state_[t])) continue;  // queued twice (far, then near)
    queueNeighbours(t, fitCell(p, t));
  }

  // Final planes of the cells holding points: seeds of the 3 x 3 cells around, all sides now
  // known; without seeds around, the grown plane.
  out->planes.resize(nc);
  out->cos.resize(nc);
  for (std::size_t t = 0; t < nc; ++t) {
    if (!cells.used[t]) continue;
    // Never grown (no seeds within reach of the growth): the global plane.
    const HeightPlane& gr = state_[t] == CellState::kNew ? gp : plane_[t];
    const Moments nb = sumsOf(t);
    const HeightPlane f = nb.w > 0 ? fitHeightPlane(nb, gr.a, gr.b, geo_.lambda) : gr;
    out->planes[t] = f;
    out->cos[t] = static_cast<float>(1.0 / std::sqrt(1.0 + f.a * f.a + f.b * f.b));
  }
}

}  // namespace voxel
}  // namespace ground_filter
