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

void Voter::vote(const VoxelGrid& g, int t, int range, ClassifyResult* cls) {
  // A voxel's vote can differ from its own points' labels only when its neighbourhood holds
  // both ground and non-ground points: a column is looked at only when its 3 x 3 columns hold
  // both labels (OR of their label masks), and then only its voxels within one z step of a
  // ground voxel and of a non-ground voxel of those columns are voted (z range [alo, ahi]).
  const std::size_t ncol = g.columns();
  const std::uint64_t* ck = g.col_key.data();
  const std::uint64_t y_mask = g.mask_y;
  const std::uint64_t* vk = g.vkey.data();
  const std::uint32_t* vs = g.vstart.data();
  const std::uint32_t* cf = g.col_first.data();
  const std::uint64_t mz = g.mask_z;
  const std::uint32_t* vg = cls->voxel_ground.data();
  const ZRange* cr = cls->col_range.data();       // + empty sentinel at ncol
  const std::uint8_t* cm = cls->col_mask.data();  // + 0 at ncol
  std::uint8_t* out = cls->ground.data();
  auto zOf = [&](std::uint32_t v) { return static_cast<std::int32_t>(vk[v] & mz); };
  std::uint64_t* acc = acc_[t].data();  // nz + 2 zeros
  // Rows of column ids with the column's label mask in the low 2 bits (id << 2 | mask; the
  // sentinel `ncol`, mask 0, where there is none): the test of a column reads its 9 entries
  // only, not their masks behind them.
  const std::int32_t none = static_cast<std::int32_t>(ncol);
  sweepColumns(
      g, bounds_[range], bounds_[range + 1], &id_rows_[t], std::int64_t{none} << 2,
      [&](std::int64_t* row, std::size_t q) {
        row[(ck[q] & y_mask) + 1] = static_cast<std::int64_t>(q << 2 | cm[q]);
      },
      [&](std::int64_t* row, std::size_t q) {
        row[(ck[q] & y_mask) + 1] = std::int64_t{none} << 2;
      },
      [&](std::size_t q, const std::int64_t* e0, const std::int64_t* e1, const std::int64_t* e2) {
        const std::int64_t mask =
            (e0[0] | e0[1] | e0[2] | e1[0] | e1[1] | e1[2] | e2[0] | e2[1] | e2[2]) & 3;
        if (mask != 3) return;
        auto id = [](std::int64_t e) { return static_cast<std::int32_t>(e >> 2); };
        const std::int32_t r0[3] = {id(e0[0]), id(e0[1]), id(e0[2])};
        const std::int32_t r1[3] = {id(e1[0]), id(e1[1]), id(e1[2])};
        const std::int32_t r2[3] = {id(e2[0]), id(e2[1]), id(e2[2])};
        const std::int32_t ids[9] = {r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2]};
        ZRange r = kEmptyRange;
        for (int k = 0; k < 9; ++k) merge(&r, cr[ids[k]]);
        const std::int32_t alo = std::max(r.glo, r.nlo) - 1;
        const std::int32_t ahi = std::min(r.ghi, r.nhi) + 1;
        // Nothing to vote unless the column's own voxels reach into [alo, ahi].
        const ZRange& own = cr[q];
        if (alo > ahi || std::max(own.ghi, own.nhi) < alo || std::min(own.glo, own.nlo) > ahi) {
          return;
        }
        // Ground and point counts per z of the 3 x 3 columns (packed ground << 32 | points,
        // dense over z, this thread's buffer), then each voted voxel sums three z entries: the
        // same integer sums as a search per column, without its data-dependent branches. In
        // each row the existing columns of y - 1 .. y + 1 are one run of voxels.
        const std::int32_t* rows[3] = {r0, r1, r2};
        std::uint32_t lo[3], hi[3];
        for (int k = 0; k < 3; ++k) {
          const std::int32_t* rk = rows[k];
          lo[k] = static_cast<std::uint32_t>(std::min(std::min(rk[0], rk[1]), rk[2]));
          std::int32_t last = 0;
          for (int j = 0; j < 3; ++j) last = std::max(last, rk[j] == none ? 0 : rk[j] + 1);
          hi[k] = std::max(lo[k], static_cast<std::uint32_t>(last));
        }
        for (int k = 0; k < 3; ++k) {
          const std::uint32_t u1 = cf[hi[k]];
          for (std::uint32_t u = cf[lo[k]]; u < u1; ++u) {
            acc[zOf(u) + 1] += (static_cast<std::uint64_t>(vg[u]) << 32) | (vs[u + 1] - vs[u]);
          }
        }
        for (std::uint32_t v = cf[q]; v < cf[q + 1]; ++v) {
          const std::int32_t z = zOf(v);
          if (z < alo) continue;
          if (z > ahi) break;
          const std::uint64_t sum = acc[z] + acc[z + 1] + acc[z + 2];
          const std::uint32_t gs = static_cast<std::uint32_t>(sum >> 32);
          const std::uint32_t ts = static_cast<std::uint32_t>(sum);
          if (2 * gs == ts) continue;  // tie: keep the per-point labels
          const std::uint8_t label = 2 * gs > ts ? 1 : 0;
          for (std::uint32_t i = vs[v]; i < vs[v + 1]; ++i) out[i] = label;
        }
        // Every voxel holds ground or non-ground points: all of them lie in the merged ranges.
        std::fill(acc + std::min(r.glo, r.nlo) + 1, acc + std::max(r.ghi, r.nhi) + 2,
                  std::uint64_t{0});
      });
}

void Voter::run(const VoxelGrid& g, int threads, WorkerPool* workers, ClassifyResult* cls) {
  const int nt = threads > 1 && g.points() >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;  // ranges of whole rows
  splitRows(g, nch, &bounds_);
  // Relabelling while voting is exact: the sums read the per-voxel ground counts of the
  // classification (never rewritten), the labels written are per point.
  id_rows_.resize(static_cast<std::size_t>(nt));
  acc_.resize(static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) {  // here: a worker may first run a chunk in a later scan
    id_rows_[t].reserve(3 * (g.ny + 2));
    acc_[t].resize(g.nz + 2, 0);  // all zero between scans: the vote clears what it adds to
  }
  workers->run(nt, nch, [&](int t, int c) { vote(g, t, c, cls); });
}

}  // namespace voxel
}  // namespace ground_filter
