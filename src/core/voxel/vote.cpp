#include "voxel/vote.h"

#include <algorithm>

#include "voxel/column_sweep.h"

namespace ground_filter {
namespace voxel {

namespace {

void merge(ZRange* r, const ZRange& o) {
  r->glo = std::min(r->glo, o.glo);
  r->ghi = std::max(r->ghi, o.ghi);
  r->nlo = std::min(r->nlo, o.nlo);
  r->nhi = std::max(r->nhi, o.nhi);
}

}  // namespace

void Voter::vote(const VoxelGrid& g, std::size_t c0, std::size_t c1, Classifier* cls) {
  // A voxel's vote can differ from its own points' labels only when its neighbourhood holds
  // both ground and non-ground points: only voxels within one z step of a ground voxel and of
  // a non-ground voxel of their 3 x 3 columns are voted (z range [alo, ahi] per column).
  const std::uint64_t* ck = g.col_key.data();
  const std::uint64_t my = g.mask_y;
  const std::uint64_t* vk = g.vkey.data();
  const std::uint32_t* vs = g.vstart.data();
  const std::uint32_t* cf = g.col_first.data();
  const std::uint64_t mz = g.mask_z;
  const std::uint32_t* vg = cls->voxel_ground.data();
  const ZRange* cr = cls->col_range.data();
  const std::uint8_t* cm = cls->col_mask.data();
  std::uint8_t* out = cls->ground.data();
  auto zOf = [&](std::uint32_t v) { return static_cast<std::int32_t>(vk[v] & mz); };
  forEachRow(g, c0, c1,
             [&](std::size_t b, std::size_t e, std::size_t pb, std::size_t pe, std::size_t nb,
                 std::size_t ne) {
               std::size_t pa = pb, na = nb;  // walk rows x - 1 and x + 1 alongside (by y)
               for (std::size_t q = b; q < e; ++q) {
                 const std::uint64_t y = ck[q] & my;
                 const std::uint64_t ylo = y == 0 ? 0 : y - 1;
                 while (pa < pe && (ck[pa] & my) < ylo) ++pa;
                 while (na < ne && (ck[na] & my) < ylo) ++na;
                 // Quick test first: does the 3 x 3 hold ground and non-ground voxels at all?
                 const bool prev_y = q > b && (ck[q - 1] & my) + 1 == y;
                 const bool next_y = q + 1 < e && (ck[q + 1] & my) == y + 1;
                 std::uint32_t mask = cm[q];
                 if (prev_y) mask |= cm[q - 1];
                 if (next_y) mask |= cm[q + 1];
                 for (std::size_t u = pa; u < pe && (ck[u] & my) <= y + 1; ++u) mask |= cm[u];
                 for (std::size_t u = na; u < ne && (ck[u] & my) <= y + 1; ++u) mask |= cm[u];
                 if (mask != 3) continue;
                 // z ranges of the ground / non-ground voxels of the 3 x 3 columns.
                 ZRange r = cr[q];
                 auto mergeRow = [&](std::size_t from, std::size_t to) {
                   for (std::size_t u = from; u < to && (ck[u] & my) <= y + 1; ++u) {
                     merge(&r, cr[u]);
                   }
                 };
                 mergeRow(pa, pe);
                 if (prev_y) merge(&r, cr[q - 1]);
                 if (next_y) merge(&r, cr[q + 1]);
                 mergeRow(na, ne);
                 const std::int32_t alo = std::max(r.glo, r.nlo) - 1;
                 const std::int32_t ahi = std::min(r.ghi, r.nhi) + 1;
                 if (alo > ahi) continue;
                 // The (up to) 9 columns around, each with a cursor moving up with z.
                 std::uint32_t cur[9], end[9];
                 int k = 0;
                 auto addRow = [&](std::size_t from, std::size_t to) {
                   for (std::size_t u = from; u < to && (ck[u] & my) <= y + 1; ++u) {
                     cur[k] = cf[u];
                     end[k++] = cf[u + 1];
                   }
                 };
                 addRow(pa, pe);
                 addRow(prev_y ? q - 1 : q, e);
                 addRow(na, ne);
                 for (std::uint32_t v = cf[q]; v < cf[q + 1]; ++v) {
                   const std::int32_t z = zOf(v);
                   if (z < alo) continue;
                   if (z > ahi) break;
                   std::uint32_t gs = 0, ts = 0;
                   for (int j = 0; j < k; ++j) {
                     std::uint32_t u = cur[j];
                     while (u < end[j] && zOf(u) < z - 1) ++u;
                     cur[j] = u;
                     for (; u < end[j] && zOf(u) <= z + 1; ++u) {
                       gs += vg[u];
                       ts += vs[u + 1] - vs[u];
                     }
                   }
                   if (2 * gs == ts) continue;  // tie: keep the per-point labels
                   const std::uint8_t label = 2 * gs > ts ? 1 : 0;
                   for (std::uint32_t i = vs[v]; i < vs[v + 1]; ++i) out[i] = label;
                 }
               }
             });
}

void Voter::run(const VoxelGrid& g, int threads, WorkerPool* workers, Classifier* cls) {
  const int nt = threads > 1 && g.points() >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;  // ranges of whole rows
  splitRows(g, nch, &bounds_);
  // Relabelling while voting is exact: the sums read the per-voxel ground counts of the
  // classification (never rewritten), the labels written are per point.
  workers->run(nt, nch, [&](int, int c) { vote(g, bounds_[c], bounds_[c + 1], cls); });
}

}  // namespace voxel
}  // namespace ground_filter
