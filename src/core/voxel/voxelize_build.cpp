// Voxelizer::build() and its sort: voxels, columns, cells and the flat / seed lists of a
// VoxelGrid from the keys of prepare() (voxelize.cpp).
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "common/huge_pages.h"
#include "common/radix_sort.h"
#include "voxel/avx2_passes.h"
#include "voxel/point_reads.h"
#include "voxel/voxelize.h"

namespace ground_filter {
namespace voxel {

namespace {

// Floats of gatherRuns()'s record per voxel: sums of x, y, z and max z - min z.
constexpr std::size_t kRunRecord = 4;

// What gatherRuns() needs, by value (no aliasing with the arrays it writes).
struct RunJob {
  const std::uint64_t* keys;   // sorted
  const std::uint32_t* order;  // slot per sorted key (not packed)
  const std::uint32_t* pidx;   // input index per slot (not all valid)
  float* xyz;                  // out: x y z in key order (3 floats a point, 1 spare at the end)
  std::uint32_t* pvox;         // out: voxel of each point
  std::uint64_t* vkey;         // out: key per voxel (+ one store past the last)
  std::uint32_t* vstart;       // out: first point per voxel
  float* vrec;                 // out: kRunRecord floats per voxel (see gatherRuns())
  std::uint64_t slot_mask;
  int low;       // key bits below the voxel key (slot bits when packed)
  float min[4];  // subtracted from (x, y, z, -z): min x, y, z and -min z
};

// Pass 1 of build(), without a branch per point or voxel (the runs are 1-2 points long on
// average: loops over them mispredict their exits): coordinates in key order, runs of equal
// keys become voxels (a store is always made, the counter moves when a run starts). Per voxel
// one 16-byte record, stored at every point of the run: the running sums of x, y, z and max z -
// min z. Vector ops update the sums and a running max of (x, y, z, -z) (lane 2: max z, lane 3:
// -min z) in all lanes at once; one record and one point store instead of eight scalar streams
// (voxelize -16 % on a KITTI frame, -34 % on a 128-beam scan). Returns the number of voxels.
//
// The points [begin, end) of `r` (end <= n, all points), their voxels numbered from r.voxel:
// ranges start and end at voxel boundaries and can run on several threads. Then a range that
// does not start at point 0 leaves its first voxel's key and start to the caller (the range
// before stores its one-past-the-last entries there), and the last point's coordinates are
// stored as three floats (not four: the fourth would be the next range's).
struct GatherRange {
  std::size_t begin, end, n, voxel;
};
template <class O, bool kPacked, bool kAllValid, class Points>
std::size_t gatherRuns(const RunJob job, const Points pts, const GatherRange r) {
  using V4 = typename O::V;
  const std::uint64_t* const k = job.keys;
  const std::uint32_t* const o = job.order;
  const std::uint32_t* const pidx = job.pidx;
  float* const xyz_out = job.xyz;
  std::uint32_t* const pv = job.pvox;
  std::uint64_t* const vk = job.vkey;
  std::uint32_t* const vs = job.vstart;
  float* const rec = job.vrec;
  const std::uint64_t slot_mask = job.slot_mask;
  const int low = job.low;
  const V4 vmin = O::v4LoadUnaligned(job.min);
  auto slotOf = [&](std::size_t i) {
    return kPacked ? static_cast<std::uint32_t>(k[i] & slot_mask) : o[i];
  };
  auto pointOf = [&](std::uint32_t s) {  // input index of slot s
    return static_cast<std::size_t>(kAllValid ? s : pidx[s]);
  };
  constexpr std::size_t kAhead = 48;  // prefetch distance of the random coordinate reads
  std::size_t nv = r.voxel;
  std::uint64_t prev = ~std::uint64_t{0};  // no key (keys use at most 63 bits)
  V4 sum = O::v4Splat(0.f), hi = O::v4Splat(0.f);
  // The loop body: with or without the prefetch (loops without a bounds test per point), and
  // for the edges of the range.
  constexpr int kFirstOfLater = 1, kLast = 2;  // edge: bits
  auto step = [&](std::size_t i, auto prefetch, auto edge) {
    if (decltype(prefetch)::value) __builtin_prefetch(pts.address(pointOf(slotOf(i + kAhead))));
    const std::uint64_t key = k[i] >> low;
    // The same float subtraction as prepare()'s key pass made lane by lane (and its negation).
    const V4 p = O::v4Sub(O::v4WithNegZ(pts.loadXyz(pointOf(slotOf(i)))), vmin);
    if (decltype(edge)::value & kLast) {
      alignas(16) float c[4];
      O::v4Store(c, p);
      std::memcpy(xyz_out + 3 * i, c, 3 * sizeof(float));
    } else {
      // Four floats: the fourth lands on the next point's x, which its own store overwrites.
      O::v4StoreUnaligned(xyz_out + 3 * i, p);
    }
    const bool first = key != prev;
    prev = key;
    if (!(decltype(edge)::value & kFirstOfLater)) {
      vk[nv] = key;  // kept when the run starts here, overwritten otherwise
      vs[nv] = static_cast<std::uint32_t>(i);
    }
    nv += first;
    const std::size_t v = nv - 1;
    pv[i] = static_cast<std::uint32_t>(v);
    // The same sums in the same order as a loop over the run would make (+0 + x first).
    sum = O::v4Add(O::v4ZeroIf(sum, first), p);
    hi = O::v4Max(O::v4LowestIf(hi, first), p);
    O::v4StoreUnaligned(rec + kRunRecord * v, O::v4SumsAndRange(sum, hi));
  };
  using Inside = std::integral_constant<int, 0>;
  if (r.begin == r.end) return nv;
  const std::size_t last = r.end - 1;
  std::size_t i = r.begin;
  if (i > 0 && i == last) {
    step(i, std::false_type(), std::integral_constant<int, kFirstOfLater | kLast>());
    return nv;
  }
  if (i > 0) step(i++, std::false_type(), std::integral_constant<int, kFirstOfLater>());
  const std::size_t with_prefetch = std::min(last, r.n > kAhead ? r.n - kAhead : 0);
  for (; i < with_prefetch; ++i) step(i, std::true_type(), Inside());
  for (; i < last; ++i) step(i, std::false_type(), Inside());
  step(last, std::false_type(), std::integral_constant<int, kLast>());
  return nv;
}

// gatherRuns() for the key layout: [packed keys][every point valid].
template <class O, class Points>
std::size_t gather(const RunJob& job, const Points& pts, bool packed, bool all_valid,
                   const GatherRange& r) {
  if (packed) {
    return all_valid ? gatherRuns<O, true, true>(job, pts, r)
                     : gatherRuns<O, true, false>(job, pts, r);
  }
  return all_valid ? gatherRuns<O, false, true>(job, pts, r)
                   : gatherRuns<O, false, false>(job, pts, r);
}

}  // namespace

void Voxelizer::sort(int threads, WorkerPool* pool, VoxelGrid* g) {
  // Several threads only on large scans (build()): on a 240 k-point scan the scatter writes of
  // two threads land in the same cache lines (32 k buckets of a few keys each), and voxelize
  // took 2x longer. Their work is split into one block a thread (fn(b), b < threads).
  auto blocks = [&](const auto& fn) { pool->run(threads, threads, [&](int, int b) { fn(b); }); };
  if (g->packed && plan_.passes >= 3 && g->keys.size() >= kTopDownSortMinPoints &&
      radixSortTopDown(plan_.lo, plan_.passes, plan_.digit, hist_.data(), &g->keys, &keys_tmp_,
                       kTopDownSortMaxBucket, threads, &block_counts_, blocks)) {
    return;
  }
  if (g->packed && threads > 1) {
    radixScatterBlocks<std::uint32_t>(plan_.lo, plan_.passes, plan_.digit, threads, &g->keys,
                                      &keys_tmp_, nullptr, nullptr, &block_counts_, blocks);
  } else if (g->packed) {
    radixScatter<std::uint32_t>(plan_.lo, plan_.passes, plan_.digit, hist_.data(), &g->keys,
                                &keys_tmp_, nullptr, nullptr);
  } else {
    radixScatter(plan_.lo, plan_.passes, plan_.digit, hist_.data(), &g->keys, &keys_tmp_, &g->order,
                 &order_tmp_);
  }
}

void Voxelizer::build(const VoxelGroundFilterParams& p, int threads, WorkerPool* pool, VoxelGrid* g,
                      CellGrid* cells) {
  const std::size_t n = g->keys.size();
  const int nt = threads > 1 && n >= parallel_min_points_ ? threads : 1;
  sort(nt, pool, g);
  cells->used.assign(cells->count(), 0);
  const std::size_t nv = gatherPoints(nt, pool, g);
  voxelPasses(p, nt, nv, pool, g, cells);
}

std::size_t Voxelizer::gatherPoints(int nt, WorkerPool* pool, VoxelGrid* g) {
  const std::size_t n = g->keys.size();
  // One pass over the sorted points: coordinates in key order, runs of equal keys become voxels.
  // A voxel is finished when the next one starts (its flags need the next key).
  resizeScratch(&g->sxyz, 3 * n + 1);
  // The gather's per-voxel outputs take one entry a point (+ one store past the last voxel):
  // they do not zero what they grow by, so the pages beyond the voxels are never touched, and
  // the voxels need no counting pass over the keys first. The other per-voxel arrays are sized
  // after the gather.
  resizeScratch(&g->vkey, n + 1);
  resizeScratch(&g->vstart, n + 1);
  resizeScratch(&vrec_, kRunRecord * n);
  const std::uint64_t* k = g->keys.data();
  const std::uint32_t* o = g->order.data();
  const bool av = g->all_valid;
  const std::uint32_t* pidx = g->point_index.data();
  float* xyz_out = g->sxyz.data();
  resizeScratch(&g->pvox, n);
  std::uint32_t* pv = g->pvox.data();
  std::uint64_t* vk = g->vkey.data();
  std::uint32_t* vs = g->vstart.data();
  const bool pk = g->packed;
  const int slot_bits = g->slot_bits;
  const int low = pk ? slot_bits : 0;
  const std::uint64_t slot_mask = (std::uint64_t{1} << slot_bits) - 1;
  // Passes without a branch per point or voxel. Pass 1 (gatherRuns(), specialised for the key
  // layout): coordinates in key order, voxels, running sums and z ranges.
  // Fields in RunJob's order: inputs, point outputs, voxel outputs, key layout, min corner.
  RunJob job = {k, o, pidx, xyz_out, pv, vk, vs, vrec_.data(), slot_mask, low, {}};
  std::copy(min_, min_ + 3, job.min);
  job.min[3] = -min_[2];
  std::size_t nv = 0;
  withOps(vec_, [&](auto ops) {
    using O = decltype(ops);
    withPoints<O>(direct_, copied() ? pxyz_.data() : nullptr, [&](const auto& pts) {
      if (nt == 1) {
        nv = gather<O>(job, pts, pk, av, GatherRange{0, n, n, 0});
        return;
      }
      // Ranges of about n / nt points that end at voxel boundaries, their voxels counted first
      // (numbered on from the ranges before), then gathered.
      range_.assign(static_cast<std::size_t>(nt) + 1, n);
      range_[0] = 0;
      for (int r = 1; r < nt; ++r) {
        std::size_t b =
            std::max(n * static_cast<std::size_t>(r) / static_cast<std::size_t>(nt), range_[r - 1]);
        while (b > 0 && b < n && (k[b] >> low) == (k[b - 1] >> low)) ++b;
        range_[r] = b;
      }
      voxel_base_.assign(static_cast<std::size_t>(nt) + 1, 0);
      pool->run(nt, nt, [&](int, int r) {
        const std::size_t b = range_[r], e = range_[r + 1];
        std::size_t starts = b < e ? 1 : 0;
        for (std::size_t i = b + 1; i < e; ++i) starts += (k[i] >> low) != (k[i - 1] >> low);
        voxel_base_[r + 1] = starts;
      });
      for (int r = 0; r < nt; ++r) voxel_base_[r + 1] += voxel_base_[r];
      pool->run(nt, nt, [&](int, int r) {
        gather<O>(job, pts, pk, av, GatherRange{range_[r], range_[r + 1], n, voxel_base_[r]});
      });
      for (int r = 1; r < nt; ++r) {  // the first voxel of every later range (GatherRange)
        if (range_[r] == range_[r + 1]) continue;
        vk[voxel_base_[r]] = k[range_[r]] >> low;
        vs[voxel_base_[r]] = static_cast<std::uint32_t>(range_[r]);
      }
      nv = voxel_base_[nt];
    });
  });
  return nv;
}

void Voxelizer::voxelPasses(const VoxelGroundFilterParams& p, int nt, std::size_t nv,
                            WorkerPool* pool, VoxelGrid* g, CellGrid* cells) {
  const bool avx2 = avx2_;  // prepare()'s choice for this scan
  const std::size_t n = g->keys.size();
  std::uint64_t* vk = g->vkey.data();
  std::uint32_t* vs = g->vstart.data();
  std::uint8_t* used = cells->used.data();
  const std::uint32_t* cxt = cells->cell_of_x.data();
  const std::uint32_t* cyt = cells->cell_of_y.data();
  const std::uint32_t min_pts = static_cast<std::uint32_t>(p.min_points_per_voxel);
  const float flat_thr = static_cast<float>(p.flatness_threshold);
  const int sy_ = g->shift_y, sx_ = g->shift_x;
  const bool local = p.local_planes;
  const std::uint64_t my = g->mask_y, mz = g->mask_z;
  g->vx.resize(nv);
  g->vy.resize(nv);
  g->vz.resize(nv);
  g->vflags.resize(nv);
  g->vcell.resize(nv);
  // Columns and flat / seed lists: at most one entry a voxel (written through pointers, cut to
  // length at the end; the buffers do not zero what they grow by).
  g->col_key.resize(nv);
  g->col_first.resize(nv + 1);
  g->flat.resize(nv);
  g->seeds.resize(nv);
  float* vx = g->vx.data();
  float* vy = g->vy.data();
  float* vz = g->vz.data();
  std::uint8_t* vflags = g->vflags.data();
  std::uint32_t* vcell = g->vcell.data();
  std::uint64_t* ckey = g->col_key.data();
  std::uint32_t* cfirst = g->col_first.data();
  std::uint32_t* flat = g->flat.data();
  std::uint32_t* seeds = g->seeds.data();
  const float* const rec = vrec_.data();
  vs[nv] = static_cast<std::uint32_t>(n);
  // Per-voxel loops without lists run in nt ranges of voxels (starts multiples of eight).
  auto voxelRanges = [&](const auto& fn) {
    pool->run(nt, nt, [&](int, int r) {
      const std::size_t t = static_cast<std::size_t>(nt);
      fn(nv * r / t & ~std::size_t{7}, r + 1 < nt ? nv * (r + 1) / t & ~std::size_t{7} : nv);
    });
  };
  // Pass 2, per voxel: centroids (a loop of its own; counts are below 2^31, so the signed
  // conversion is exact), then column, cell, flags and the flat / seed lists.
  voxelRanges([&](std::size_t b, std::size_t e) {
    const std::size_t v_scalar =
        b + (avx2 ? centroidsAvx2(rec + kRunRecord * b, vs + b, e - b, vx + b, vy + b, vz + b) : 0);
    for (std::size_t v = v_scalar; v < e; ++v) {
      const float inv = 1.f / static_cast<float>(static_cast<std::int32_t>(vs[v + 1] - vs[v]));
      vx[v] = rec[kRunRecord * v] * inv;
      vy[v] = rec[kRunRecord * v + 1] * inv;
      vz[v] = rec[kRunRecord * v + 2] * inv;
    }
  });
  // Flags and the column, flat and seed lists: each voxel's from its key, its neighbours' keys,
  // its count and z range (the AVX2 pass does blocks of eight; voxelFlags() the rest). Then each
  // voxel's cell (its column's), and per column its key and its cell marked used, in loops of
  // their own: one loop doing it all kept too many arrays live (stack reloads, 77 instructions
  // a voxel).
  const VoxelFlagsJob fj = {vk, vs, rec, kRunRecord, nv, sy_, mz, min_pts, flat_thr, local};
  VoxelLists lists = {cfirst, flat, seeds, 0, 0, 0};
  const std::size_t v_done = avx2 ? voxelFlagsAvx2(fj, vflags, &lists) : 0;
  voxelFlags(fj, v_done, nv, vflags, &lists);
  const std::size_t ncol = lists.ncol, nflat = lists.nflat, nseed = lists.nseed;
  voxelRanges([&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      const std::uint64_t key = vk[v];
      vcell[v] = cxt[key >> sx_] + cyt[(key >> sy_) & my];  // the column's cell
    }
  });
  for (std::size_t c = 0; c < ncol; ++c) {
    ckey[c] = vk[cfirst[c]] >> sy_;
    used[vcell[cfirst[c]]] = 1;
  }
  cfirst[ncol] = static_cast<std::uint32_t>(nv);
  g->vkey.resize(nv);
  g->vstart.resize(nv + 1);
  g->col_key.resize(ncol);
  g->col_first.resize(ncol + 1);
  g->flat.resize(nflat);
  g->seeds.resize(nseed);
}

}  // namespace voxel
}  // namespace ground_filter
