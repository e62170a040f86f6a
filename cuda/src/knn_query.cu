// The KNN query kernel: one warp per query over the hashed grid levels.
#include "cuda_util.cuh"
#include "knn_query.cuh"

namespace ground_filter {
namespace cuda_impl {

namespace {

/// The warp's sorted top-K list: lane l holds slots l and l + 32.
struct WarpList {
  float dlo, dhi;
  int ilo, ihi;
  float kd;  // K-th slot (broadcast)
  int ki;
};

/// The K-th entry (distance, index) of the warp's sorted list, broadcast to every lane: the
/// bound that insert and merge keep up to date.
template <bool kTwoHalves>
__device__ inline void refreshKth(WarpList& w, int k) {
  const unsigned full = 0xffffffffu;
  const int kl = (k - 1) & 31;
  if (!kTwoHalves || k <= 32) {
    w.kd = __shfl_sync(full, w.dlo, kl);
    w.ki = __shfl_sync(full, w.ilo, kl);
  } else {
    w.kd = __shfl_sync(full, w.dhi, kl);
    w.ki = __shfl_sync(full, w.ihi, kl);
  }
}

template <bool kTwoHalves>
__device__ inline void warpInsert(WarpList& w, float d, int id, int lane, int k) {
  const unsigned full = 0xffffffffu;
  int pos = __popc(__ballot_sync(full, pairLess(w.dlo, w.ilo, d, id)));
  float phi = 0.f;
  int pihi = 0;
  if (kTwoHalves) {
    pos += __popc(__ballot_sync(full, pairLess(w.dhi, w.ihi, d, id)));
    const float last_d = __shfl_sync(full, w.dlo, 31);
    const int last_i = __shfl_sync(full, w.ilo, 31);
    phi = __shfl_up_sync(full, w.dhi, 1);
    pihi = __shfl_up_sync(full, w.ihi, 1);
    if (lane == 0) {
      phi = last_d;
      pihi = last_i;
    }
  }
  const float plo = __shfl_up_sync(full, w.dlo, 1);
  const int pilo = __shfl_up_sync(full, w.ilo, 1);
  if (lane > pos) {
    w.dlo = plo;
    w.ilo = pilo;
  } else if (lane == pos) {
    w.dlo = d;
    w.ilo = id;
  }
  if (kTwoHalves) {
    if (lane + 32 > pos) {
      w.dhi = phi;
      w.ihi = pihi;
    } else if (lane + 32 == pos) {
      w.dhi = d;
      w.ihi = id;
    }
  }
  refreshKth<kTwoHalves>(w, k);
}

/// Bitonic sort of one (key, cell) pair per lane by increasing key, across the warp.
__device__ inline void warpSortCells(float& key, uint2& cell, int lane) {
  const unsigned full = 0xffffffffu;
  for (int size = 2; size <= 32; size <<= 1) {
    for (int stride = size >> 1; stride > 0; stride >>= 1) {
      const float ok = __shfl_xor_sync(full, key, stride);
      const unsigned ox = __shfl_xor_sync(full, cell.x, stride);
      const unsigned oy = __shfl_xor_sync(full, cell.y, stride);
      const bool ascending = (lane & size) == 0 || size == 32;
      const bool lower = (lane & stride) == 0;
      if (lower == ascending ? ok < key : ok > key) {
        key = ok;
        cell = make_uint2(ox, oy);
      }
    }
  }
}

/// Largest squared distance from q to the k points of sorted positions [w0, w0 + k), warp-wide.
__device__ inline float windowMax(const float4* __restrict__ pts, long long w0, int k,
                                  const float4& q, int lane) {
  float dmax = 0.f;
  if (lane < k) {
    const float4 p = pts[w0 + lane];
    dmax = sqDist(p.x, p.y, p.z, q.x, q.y, q.z);
  }
  if (lane + 32 < k) {
    const float4 p = pts[w0 + lane + 32];
    dmax = fmaxf(dmax, sqDist(p.x, p.y, p.z, q.x, q.y, q.z));
  }
  for (int o = 16; o > 0; o >>= 1) dmax = fmaxf(dmax, __shfl_xor_sync(0xffffffffu, dmax, o));
  return dmax;
}

/// Bitonic sort of one (distance, index) pair per lane by increasing (distance, index).
__device__ inline void warpSortPairs(float& d, int& id, int lane) {
  const unsigned full = 0xffffffffu;
  for (int size = 2; size <= 32; size <<= 1) {
    for (int stride = size >> 1; stride > 0; stride >>= 1) {
      const float od = __shfl_xor_sync(full, d, stride);
      const int oi = __shfl_xor_sync(full, id, stride);
      const bool ascending = (lane & size) == 0 || size == 32;
      const bool lower = (lane & stride) == 0;
      if (lower == ascending ? pairLess(od, oi, d, id) : pairLess(d, id, od, oi)) {
        d = od;
        id = oi;
      }
    }
  }
}

/// warpSortCells, skipped when at most one cell of the batch is non-empty (always so for the
/// query's own cell, shell 0).
__device__ inline void warpSortNonEmptyCells(float& key, uint2& cell, int lane) {
  if (__popc(__ballot_sync(0xffffffffu, cell.y != 0)) > 1) warpSortCells(key, cell, lane);
}

/// Compare-exchange step of a bitonic merge: lane keeps the smaller pair of (own, partner at
/// lane ^ stride) when it is the lower lane of the two, else the larger.
__device__ inline void bitonicStep(float& d, int& id, int lane, int stride) {
  const float od = __shfl_xor_sync(0xffffffffu, d, stride);
  const int oi = __shfl_xor_sync(0xffffffffu, id, stride);
  const bool lower = (lane & stride) == 0;
  if (lower == pairLess(od, oi, d, id)) {
    d = od;
    id = oi;
  }
}

/// Sorts a bitonic sequence of one pair per lane into increasing order.
__device__ inline void bitonicMerge(float& d, int& id, int lane) {
  for (int stride = 16; stride > 0; stride >>= 1) bitonicStep(d, id, lane, stride);
}

/// Merges a batch of pairs (one per lane, non-entrants set to (inf, kEmptyIndex)) into the sorted
/// list in one go: the list keeps the smallest 32 (one half) or 64 (two halves) pairs of both,
/// which are exactly the slots that one insertion per entrant would leave (rows are unique, so
/// (distance, index) orders them totally).
template <bool kTwoHalves>
__device__ inline void warpMerge(WarpList& w, float d, int id, int lane, int k,
                                 bool presorted = false) {
  const unsigned full = 0xffffffffu;
  if (!presorted) warpSortPairs(d, id, lane);
  // Reversed, the sorted batch against an ascending half gives a bitonic sequence of the
  // smaller of each pair: the 32 smallest of the two.
  float rd = __shfl_sync(full, d, 31 - lane);
  int ri = __shfl_sync(full, id, 31 - lane);
  if (kTwoHalves) {
    // Smallest 32 of (hi, batch); every pair of lo stays in the list (at most 63 are smaller).
    if (pairLess(rd, ri, w.dhi, w.ihi)) {
      w.dhi = rd;
      w.ihi = ri;
    }
    bitonicMerge(w.dhi, w.ihi, lane);
    rd = __shfl_sync(full, w.dhi, 31 - lane);
    ri = __shfl_sync(full, w.ihi, 31 - lane);
    // lo and the reversed new hi: element-wise min and max split them into the smallest and the
    // largest 32, each a bitonic sequence.
    const bool swap = pairLess(rd, ri, w.dlo, w.ilo);
    w.dhi = swap ? w.dlo : rd;
    w.ihi = swap ? w.ilo : ri;
    if (swap) {
      w.dlo = rd;
      w.ilo = ri;
    }
    bitonicMerge(w.dlo, w.ilo, lane);
    bitonicMerge(w.dhi, w.ihi, lane);
  } else {
    if (pairLess(rd, ri, w.dlo, w.ilo)) {
      w.dlo = rd;
      w.ilo = ri;
    }
    bitonicMerge(w.dlo, w.ilo, lane);
  }
  refreshKth<kTwoHalves>(w, k);
}

/// Per-query work counters of searchQuery (CudaKnnOptions::collect_stats).
struct QueryCounters {
  unsigned int cand = 0, ins = 0, shell = 0, lev = 0;
  int bits = 0;
  float lim = 0.f;
};

/// Upper bound of q's K-th squared distance: any k points bound it. Here the k points before q
/// and the k points from q on in Morton order, whichever is closer: where the curve jumps far on
/// one side of q, the other side still gives a tight bound. Candidates and cells beyond the bound
/// are skipped from the start.
__device__ __forceinline__ float kthDistanceBound(const float4* __restrict__ pts, int n,
                                                  long long qi, int k, const float4& q, int lane) {
  float lim = INFINITY;
  if (n >= k) {
    const long long lo = max(qi - k + 1, 0ll), hi = min(qi, static_cast<long long>(n - k));
    lim = fminf(windowMax(pts, lo, k, q, lane), windowMax(pts, hi, k, q, lane));
  }
  return lim;
}

/// Level: the finest whose own cell holds >= min_points points, or, if finer, the finest whose
/// cells are at least the bound's radius / kBoundCells (the k window points then lie within
/// kBoundCells + 1 shells).
/// The second rule keeps isolated points from landing on a coarse level whose shells hold a
/// large part of the cloud. Lanes test one level each.
__device__ __forceinline__ int startLevel(const GridDesc& g,
                                          const unsigned long long* __restrict__ tkeys,
                                          const uint2* __restrict__ tvals, std::uint32_t qx,
                                          std::uint32_t qy, std::uint32_t qz, float lim, int lane) {
  const unsigned full = 0xffffffffu;
  bool ok = false, ok_r = false;
  if (lane < g.nlev) {
    const LevelDesc& lv = g.lv[lane];
    const int s = kCoordBits - lv.bits;
    const uint2 c = lookupCell(tkeys, tvals, lv, morton(qx >> s, qy >> s, qz >> s));
    ok = static_cast<int>(c.y) >= g.min_points;
    ok_r = kBoundCells * lv.cell >= sqrtf(lim);
  }
  const unsigned okm = __ballot_sync(full, ok), okr = __ballot_sync(full, ok_r);
  return min(okm ? __ffs(okm) - 1 : g.nlev - 1, okr ? __ffs(okr) - 1 : g.nlev - 1);
}

/// The query's cell (cx, cy, cz) on one level: cell edge cs, cells per axis last + 1.
struct QueryCell {
  int cx, cy, cz, last;
  float cs;
};

/// Cell index of coordinate v clamped to [-2, last + 2] (no int overflow for huge radii).
__device__ __forceinline__ int clampedCell(float v, float o, const QueryCell& qc) {
  return static_cast<int>(
      fminf(fmaxf(floorf((v - o) / qc.cs), -2.f), static_cast<float>(qc.last + 2)));
}

/// Cell range [x0, x1] x [y0, y1] x [z0, z1] of shell r: the block of Chebyshev radius r, cut to
/// the cells that can hold a point within `reach` (squared) of q.
struct ShellBox {
  int x0, x1, y0, y1, z0, z1;
};

__device__ __forceinline__ ShellBox shellBox(const GridDesc& g, const QueryCell& qc, int r,
                                             const float4& q, float reach) {
  ShellBox b;
  b.x0 = max(qc.cx - r, 0);
  b.x1 = min(qc.cx + r, qc.last);
  b.y0 = max(qc.cy - r, 0);
  b.y1 = min(qc.cy + r, qc.last);
  b.z0 = max(qc.cz - r, 0);
  b.z1 = min(qc.cz + r, qc.last);
  if (reach < INFINITY) {  // only cells that can hold a point within it
    const float rad = sqrtf(reach) + g.eps;
    b.x0 = max(b.x0, clampedCell(q.x - rad, g.ox, qc) - 1);
    b.x1 = min(b.x1, clampedCell(q.x + rad, g.ox, qc) + 1);
    b.y0 = max(b.y0, clampedCell(q.y - rad, g.oy, qc) - 1);
    b.y1 = min(b.y1, clampedCell(q.y + rad, g.oy, qc) + 1);
    b.z0 = max(b.z0, clampedCell(q.z - rad, g.oz, qc) - 1);
    b.z1 = min(b.z1, clampedCell(q.z + rad, g.oz, qc) + 1);
  }
  return b;
}

/// Lane's cell t of the box, looked up when it lies on shell r and its box distance to q is
/// within min(w.kd, lim): `cell` (first sorted point, count; count 0 otherwise) and `key` (the
/// box distance, +inf for an empty cell).
__device__ __forceinline__ void shellCell(const GridDesc& g, const LevelDesc& lv,
                                          const unsigned long long* __restrict__ tkeys,
                                          const uint2* __restrict__ tvals, const QueryCell& qc,
                                          const ShellBox& b, int r, int t, int total,
                                          const float4& q, float kd, float lim, uint2& cell,
                                          float& key) {
  cell = make_uint2(0u, 0u);
  key = INFINITY;
  if (t >= total) return;
  const int nx = b.x1 - b.x0 + 1, ny = b.y1 - b.y0 + 1;
  const int ix = b.x0 + t % nx, iy = b.y0 + (t / nx) % ny, iz = b.z0 + t / (nx * ny);
  const int cheb = max(max(abs(ix - qc.cx), abs(iy - qc.cy)), abs(iz - qc.cz));
  if (cheb != r) return;
  const float cs = qc.cs, eps = g.eps;
  const float lx = g.ox + ix * cs, ly = g.oy + iy * cs, lz = g.oz + iz * cs;
  const float ex = fmaxf(fmaxf(lx - q.x, q.x - (lx + cs)) - eps, 0.f);
  const float ey = fmaxf(fmaxf(ly - q.y, q.y - (ly + cs)) - eps, 0.f);
  const float ez = fmaxf(fmaxf(lz - q.z, q.z - (lz + cs)) - eps, 0.f);
  const float box = ex * ex + ey * ey + ez * ez;
  if (box <= fminf(kd, lim)) {
    cell = lookupCell(tkeys, tvals, lv,
                      morton(static_cast<std::uint32_t>(ix), static_cast<std::uint32_t>(iy),
                             static_cast<std::uint32_t>(iz)));
    if (cell.y) key = box;
  }
}

/// What the candidate steps of one query read: the sorted points, the ends of the runs of
/// identical points (null: no skip), the query, its bound, K, the merge threshold, the lane.
struct QueryArgs {
  const float4* __restrict__ pts;
  const unsigned int* __restrict__ run_stop;
  float4 q;
  float lim;
  int k, merge_min, lane;
};

/// The candidate at sorted position spos (valid lanes) against the list: d, id and the end of
/// its run of identical points come back for the skip of consumeCells.
template <bool kTwoHalves>
__device__ __forceinline__ void consumeCandidate(const QueryArgs& a, bool valid, unsigned int spos,
                                                 WarpList& w, unsigned int& n_ins, float& d,
                                                 int& id, unsigned int& stop) {
  const unsigned full = 0xffffffffu;
  const int lane = a.lane, k = a.k;
  const float lim = a.lim;
  d = INFINITY;
  id = kEmptyIndex;
  stop = 0;
  if (valid) {
    const float4 p = a.pts[spos];
    if (a.run_stop) stop = a.run_stop[spos];
    d = sqDist(p.x, p.y, p.z, a.q.x, a.q.y, a.q.z);
    id = __float_as_int(p.w);
  }
  const bool useful = valid && d <= lim;
  unsigned m = __ballot_sync(full, useful && pairLess(d, id, w.kd, w.ki));
  if (__popc(m) > 1 && __shfl_sync(full, w.ilo, 0) == kEmptyIndex) {
    // Empty list: the batch, sorted, becomes the list (saves one insertion per point).
    float sd = useful ? d : INFINITY;
    int si = useful ? id : kEmptyIndex;
    warpSortPairs(sd, si, lane);
    w.dlo = sd;
    w.ilo = si;
    const int kl = (k - 1) & 31;
    w.kd = (!kTwoHalves || k <= 32) ? __shfl_sync(full, w.dlo, kl) : INFINITY;
    w.ki = (!kTwoHalves || k <= 32) ? __shfl_sync(full, w.ilo, kl) : kEmptyIndex;
    n_ins += __popc(m);
    m = 0;
  } else if (a.merge_min > 0 && __popc(m) >= a.merge_min) {
    // Many entrants: one bitonic merge costs about as much as 5 single insertions.
    const bool in = (m >> lane) & 1u;
    warpMerge<kTwoHalves>(w, in ? d : INFINITY, in ? id : kEmptyIndex, lane, k);
    n_ins += __popc(m);
    m = 0;
  }
  while (m) {
    const int src = __ffs(m) - 1;
    const float dd = __shfl_sync(full, d, src);
    const int ii = __shfl_sync(full, id, src);
    warpInsert<kTwoHalves>(w, dd, ii, lane, k);
    ++n_ins;
    m &= ~(1u << src);
    m &= __ballot_sync(full, useful && pairLess(d, id, w.kd, w.ki));
  }
}

/// Part of a heavy query: the points of sorted 32-blocks b with b mod nparts == part of the
/// warp's cells, cell by cell (a partition of the points that no level or pruning choice
/// changes).
template <bool kTwoHalves>
__device__ __forceinline__ void consumeCellsOfPart(const QueryArgs& a, const uint2& cell, int part,
                                                   int nparts, WarpList& w, QueryCounters& c) {
  const unsigned full = 0xffffffffu;
  unsigned int todo = __ballot_sync(full, cell.y > 0);
  while (todo) {
    const int j = __ffs(todo) - 1;
    todo &= todo - 1;
    const unsigned int s0 = __shfl_sync(full, cell.x, j), s1 = s0 + __shfl_sync(full, cell.y, j);
    c.cand += s1 - s0;
    const unsigned int b0 = s0 >> 5;
    const unsigned int first = b0 + (part + nparts - b0 % nparts) % nparts;
    for (unsigned int blk = first; (blk << 5) < s1; blk += nparts) {
      const unsigned int spos = (blk << 5) + a.lane;
      float d;
      int id;
      unsigned int stop;
      consumeCandidate<kTwoHalves>(a, spos >= s0 && spos < s1, spos, w, c.ins, d, id, stop);
    }
  }
}

/// The points of the warp's cells, their ranges concatenated across the warp, 32 at a time.
/// Returns false once more than `abort_cands` candidates (0: never) were loaded (`scanned`).
template <bool kTwoHalves>
__device__ __forceinline__ bool consumeCells(const QueryArgs& a, const uint2& cell,
                                             unsigned int abort_cands, unsigned int& scanned,
                                             WarpList& w, QueryCounters& c) {
  const unsigned full = 0xffffffffu;
  const int lane = a.lane;
  unsigned int incl = cell.y;
  for (int o = 1; o < kWarp; o <<= 1) {
    const unsigned int v = __shfl_up_sync(full, incl, o);
    if (lane >= o) incl += v;
  }
  const unsigned int excl = incl - cell.y;
  const unsigned int count = __shfl_sync(full, incl, 31);
  c.cand += count;
  for (unsigned int cb = 0; cb < count; cb += kWarp) {
    // Too many candidates for one warp: leave the query to the heavy kernel (warp-uniform).
    scanned += kWarp;
    if (abort_cands && scanned > abort_cands) return false;
    const unsigned int gpos = cb + lane;
    int owner = 0;  // first lane whose inclusive sum exceeds gpos
    for (int step = 16; step > 0; step >>= 1) {
      const unsigned int v = __shfl_sync(full, incl, owner + step - 1);
      if (v <= gpos) owner += step;
    }
    const unsigned int ostart = __shfl_sync(full, cell.x, owner);
    const unsigned int oexcl = __shfl_sync(full, excl, owner);
    const unsigned int spos = ostart + (gpos - oexcl);  // sorted position (valid lanes)
    float d;
    int id;
    unsigned int stop;
    consumeCandidate<kTwoHalves>(a, gpos < count, spos, w, c.ins, d, id, stop);
    // Exact skip inside runs of identical points (e.g. thousands of no-return points at the
    // origin): they share one distance and their indices ascend (stable sort), so once the
    // last lane's point cannot enter the list (beyond lim, or not before the K-th pair) no
    // later member of its run can.
    if (a.run_stop) {
      const int last = min(kWarp - 1, static_cast<int>(count - cb) - 1);
      const float d_last = __shfl_sync(full, d, last);
      const int id_last = __shfl_sync(full, id, last);
      const unsigned int pos_last = __shfl_sync(full, spos, last);
      const unsigned int stop_last = __shfl_sync(full, stop, last);
      if (stop_last > pos_last + 1 &&
          (!(d_last <= a.lim) || !pairLess(d_last, id_last, w.kd, w.ki))) {
        cb += stop_last - pos_last - 1;
      }
    }
  }
  return true;
}

/// Distance from q to the outside of the visited block of cells of shell r (grid edges
/// excluded); +inf when the block covers the whole grid.
__device__ __forceinline__ float outsideDistance(const GridDesc& g, const QueryCell& qc, int r,
                                                 const float4& q) {
  const int cx = qc.cx, cy = qc.cy, cz = qc.cz, last = qc.last;
  const float cs = qc.cs;
  float bound = INFINITY;
  if (cx - r > 0) bound = fminf(bound, q.x - (g.ox + (cx - r) * cs));
  if (cx + r < last) bound = fminf(bound, g.ox + (cx + r + 1) * cs - q.x);
  if (cy - r > 0) bound = fminf(bound, q.y - (g.oy + (cy - r) * cs));
  if (cy + r < last) bound = fminf(bound, g.oy + (cy + r + 1) * cs - q.y);
  if (cz - r > 0) bound = fminf(bound, q.z - (g.oz + (cz - r) * cs));
  if (cz + r < last) bound = fminf(bound, g.oz + (cz + r + 1) * cs - q.z);
  return bound;
}

/// The search of one query by one warp. Part `part` of `nparts` > 1: the warp takes only the points
/// of the sorted 32-blocks b with b mod nparts == part, a fixed partition, and runs the search on
/// them alone (its own K-th distance prunes and stops it), so the union of the parts' lists holds
/// the query's K nearest (kHeavyWarps warps of one block finish a heavy query). Returns false,
/// with the list unfinished, once it has loaded more than `abort_cands` candidates (0: never).
template <bool kTwoHalves, bool kSortCells>
__device__ __forceinline__ bool searchQuery(const GridDesc& g, const float4* __restrict__ pts,
                                            const unsigned long long* __restrict__ tkeys,
                                            const uint2* __restrict__ tvals, int n,
                                            const unsigned int* __restrict__ run_stop, long long qi,
                                            int k, int merge_min, int part, int nparts,
                                            unsigned int abort_cands, int lane, WarpList& w,
                                            QueryCounters& c) {
  unsigned int scanned = 0;  // candidates loaded so far (runs skipped do not count)
  const float4 q = pts[qi];
  const std::uint32_t qx = quantize(q.x, g.ox, g.inv), qy = quantize(q.y, g.oy, g.inv),
                      qz = quantize(q.z, g.oz, g.inv);
  const float lim = kthDistanceBound(pts, n, qi, k, q, lane);
  int li = startLevel(g, tkeys, tvals, qx, qy, qz, lim, lane);
  const QueryArgs args{pts, run_stop, q, lim, k, merge_min, lane};

  for (;;) {  // one pass per level tried; a pass that starves moves to the next coarser level
    ++c.lev;
    const LevelDesc& lv = g.lv[li];
    const int shift = kCoordBits - lv.bits;
    const QueryCell qc{static_cast<int>(qx >> shift), static_cast<int>(qy >> shift),
                       static_cast<int>(qz >> shift), (1 << lv.bits) - 1, lv.cell};
    w.dlo = w.dhi = w.kd = INFINITY;
    w.ilo = w.ihi = w.ki = kEmptyIndex;
    bool restart = false;

    for (int r = 0;; ++r) {
      ++c.shell;
      // squared distance a useful point can have
      const ShellBox b = shellBox(g, qc, r, q, fminf(w.kd, lim));
      const int nx = b.x1 - b.x0 + 1, ny = b.y1 - b.y0 + 1, nz = b.z1 - b.z0 + 1;
      const int total = (nx > 0 && ny > 0 && nz > 0) ? nx * ny * nz : 0;
      for (int cbase = 0; cbase < total; cbase += kWarp) {
        // Each lane looks up one cell of the shell.
        uint2 cell;
        float key;
        shellCell(g, lv, tkeys, tvals, qc, b, r, cbase + lane, total, q, w.kd, lim, cell, key);
        if (kSortCells) warpSortNonEmptyCells(key, cell, lane);
        if (nparts > 1) {
          consumeCellsOfPart<kTwoHalves>(args, cell, part, nparts, w, c);
          continue;
        }
        if (!consumeCells<kTwoHalves>(args, cell, abort_cands, scanned, w, c)) return false;
      }
      float bound = outsideDistance(g, qc, r, q);
      if (bound == INFINITY) break;  // the block covers the whole grid
      bound -= g.eps;
      // Every point within lim visited: nothing farther can enter (ends a part of a heavy query
      // whose own points within lim are fewer than K).
      if (bound > 0.f && lim <= bound * bound) break;
      if (w.ki != kEmptyIndex && bound > 0.f && w.kd <= bound * bound) break;
      // Still short of k points two shells out while the bound's ball needs many more shells:
      // this level is too fine around q; start again one level coarser rather than walking many
      // empty shells.
      if (w.ki == kEmptyIndex && r >= kStarveShells && !(sqrtf(lim) <= (kBoundCells + 1) * qc.cs) &&
          li + 1 < g.nlev) {
        restart = true;
        break;
      }
    }
    if (!restart) break;
    ++li;
  }

  c.bits = g.lv[li].bits;
  c.lim = lim;
  return true;
}

/// Writes the list of sorted point qi (row qi of the output).
template <bool kTwoHalves>
__device__ inline void writeRow(const WarpList& w, long long qi, int k, int lane,
                                std::int32_t* __restrict__ out_idx, float* __restrict__ out_d2) {
  const std::size_t row = static_cast<std::size_t>(qi) * k;
  if (lane < k) {
    out_idx[row + lane] = w.ilo == kEmptyIndex ? -1 : w.ilo;
    if (out_d2) out_d2[row + lane] = w.ilo == kEmptyIndex ? INFINITY : w.dlo;
  }
  if (kTwoHalves && lane + 32 < k) {
    out_idx[row + lane + 32] = w.ihi == kEmptyIndex ? -1 : w.ihi;
    if (out_d2) out_d2[row + lane + 32] = w.ihi == kEmptyIndex ? INFINITY : w.dhi;
  }
}

/// One warp per query; queries [base, end) of the Morton-sorted points; row s of the output holds
/// the list of sorted point s (original indices). kTwoHalves: k > 32. kSortCells: visit the cells
/// of each batch nearest first (the K-th distance shrinks sooner, fewer insertions). A query whose
/// cells hold more than `abort_cands` candidates (an isolated point, whose K-th neighbour lies
/// tens of metres away) is left to knnHeavyKernel: its index goes to heavy[base + ...].
template <bool kTwoHalves, bool kSortCells>
__global__ void __launch_bounds__(kQueryBlock, kQueryBlocksPerSm)
    knnKernel(const __grid_constant__ GridDesc g, const float4* __restrict__ pts,
              const unsigned long long* __restrict__ tkeys, const uint2* __restrict__ tvals, int n,
              const unsigned int* __restrict__ run_stop, int base, int end, int k, int merge_min,
              unsigned int abort_cands, unsigned int* __restrict__ heavy,
              unsigned int* __restrict__ heavy_count, std::int32_t* __restrict__ out_idx,
              float* __restrict__ out_d2, unsigned long long* __restrict__ stats) {
  const int lane = threadIdx.x & 31;
  const long long qi =
      base + ((static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x) >> 5);
  if (qi >= end) return;  // uniform per warp
  const long long t_start = stats ? clock64() : 0;
  WarpList w;
  QueryCounters c;
  const bool done = searchQuery<kTwoHalves, kSortCells>(g, pts, tkeys, tvals, n, run_stop, qi, k,
                                                        merge_min, 0, 1, abort_cands, lane, w, c);
  if (!done) {
    if (lane == 0) heavy[base + atomicAdd(heavy_count, 1u)] = static_cast<unsigned int>(qi);
  } else {
    writeRow<kTwoHalves>(w, qi, k, lane, out_idx, out_d2);
  }
  if (stats && lane == 0) {
    const unsigned long long cyc = static_cast<unsigned long long>(clock64() - t_start);
    atomicAdd(&stats[kStatCandidates], c.cand);
    atomicAdd(&stats[kStatInsertions], c.ins);
    atomicAdd(&stats[kStatShells], c.shell);
    atomicAdd(&stats[kStatLevels], c.lev);
    atomicAdd(&stats[kStatCycles], cyc);
    if (!done) atomicAdd(&stats[kStatHeavy], 1ull);
    if (cyc > 100000) atomicAdd(&stats[kStatOver100k], 1ull);
    if (cyc > 1000000) atomicAdd(&stats[kStatOver1M], 1ull);
    if (atomicMax(&stats[kStatMaxCycles], cyc) < cyc) {  // the slowest so far (racy: diagnostics)
      stats[kStatSlowCand] = c.cand;
      stats[kStatSlowIns] = c.ins;
      stats[kStatSlowShells] = c.shell;
      stats[kStatSlowLevels] = c.lev;
      stats[kStatSlowBits] = c.bits;
      stats[kStatSlowLim] = __float_as_uint(c.lim);
      stats[kStatSlowKd] = __float_as_uint(w.kd);
    }
  }
}

/// The queries knnKernel left: kHeavyWarps warps per query, each over its part of the candidates,
/// then warp 0 merges the parts' lists (their points are disjoint, so the merged list is exact).
/// Blocks stride over the heavy[base ...] list (its length is on the device: no host sync).
template <bool kTwoHalves, bool kSortCells>
__global__ void __launch_bounds__(kHeavyWarps* kWarp, 2)
    knnHeavyKernel(const __grid_constant__ GridDesc g, const float4* __restrict__ pts,
                   const unsigned long long* __restrict__ tkeys, const uint2* __restrict__ tvals,
                   int n, int base, int k, int merge_min, const unsigned int* __restrict__ heavy,
                   const unsigned int* __restrict__ heavy_count, std::int32_t* __restrict__ out_idx,
                   float* __restrict__ out_d2) {
  __shared__ float sd[kHeavyWarps][2 * kWarp];
  __shared__ int si[kHeavyWarps][2 * kWarp];
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  const unsigned int nh = *heavy_count;
  for (unsigned int h = blockIdx.x; h < nh; h += gridDim.x) {  // uniform per block
    const long long qi = heavy[base + h];
    WarpList w;
    QueryCounters c;
    searchQuery<kTwoHalves, kSortCells>(g, pts, tkeys, tvals, n, nullptr, qi, k, merge_min, warp,
                                        kHeavyWarps, 0u, lane, w, c);
    sd[warp][lane] = w.dlo;
    si[warp][lane] = w.ilo;
    sd[warp][lane + kWarp] = kTwoHalves ? w.dhi : INFINITY;
    si[warp][lane + kWarp] = kTwoHalves ? w.ihi : kEmptyIndex;
    __syncthreads();
    if (warp == 0) {
      for (int o = 1; o < kHeavyWarps; ++o) {
        warpMerge<kTwoHalves>(w, sd[o][lane], si[o][lane], lane, k, true);
        if (kTwoHalves) {
          warpMerge<kTwoHalves>(w, sd[o][lane + kWarp], si[o][lane + kWarp], lane, k, true);
        }
      }
      writeRow<kTwoHalves>(w, qi, k, lane, out_idx, out_d2);
    }
    __syncthreads();
  }
}

}  // namespace

void launchKnnQuery(const GridDesc& g, const float4* pts, const unsigned long long* tkeys,
                    const uint2* tvals, const unsigned int* run_stop, int n, int base, int end,
                    int k, bool sort_cells, int merge_min, unsigned int abort_cands,
                    unsigned int* heavy, unsigned int* heavy_count, int heavy_blocks,
                    std::int32_t* out_idx, float* out_d2, unsigned long long* stats,
                    cudaStream_t st) {
  if (end <= base) return;
  const unsigned int blocks = blocksFor(static_cast<std::size_t>(end - base) * kWarp, kQueryBlock);
  // Variants: k > 32 (two list halves), cells nearest first.
#define GF_KNN_LAUNCH(TWO, SORT)                                                                  \
  do {                                                                                            \
    knnKernel<TWO, SORT><<<blocks, kQueryBlock, 0, st>>>(g, pts, tkeys, tvals, n, run_stop, base, \
                                                         end, k, merge_min, abort_cands, heavy,   \
                                                         heavy_count, out_idx, out_d2, stats);    \
    GF_CUDA_CHECK_LAUNCH();                                                                       \
    if (abort_cands) {                                                                            \
      knnHeavyKernel<TWO, SORT><<<heavy_blocks, kHeavyWarps * kWarp, 0, st>>>(                    \
          g, pts, tkeys, tvals, n, base, k, merge_min, heavy, heavy_count, out_idx, out_d2);      \
      GF_CUDA_CHECK_LAUNCH();                                                                     \
    }                                                                                             \
  } while (0)
  const bool two = k > 32;
  if (sort_cells) {
    if (two)
      GF_KNN_LAUNCH(true, true);
    else
      GF_KNN_LAUNCH(false, true);
  } else {
    if (two)
      GF_KNN_LAUNCH(true, false);
    else
      GF_KNN_LAUNCH(false, false);
  }
#undef GF_KNN_LAUNCH
}

}  // namespace cuda_impl
}  // namespace ground_filter
