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

void Voter::vote(const VoxelGrid& g, int t, int range, Classifier* cls) {
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
  // Rows of column ids (the sentinel `ncol` where there is none).
  const std::int32_t none = static_cast<std::int32_t>(ncol);
  sweepColumns(
      g, bounds_[range], bounds_[range + 1], &id_rows_[t], none,
      [&](std::int32_t* row, std::size_t q) {
        row[(ck[q] & y_mask) + 1] = static_cast<std::int32_t>(q);
      },
      [&](std::int32_t* row, std::size_t q) { row[(ck[q] & y_mask) + 1] = none; },
      [&](std::size_t q, const std::int32_t* r0, const std::int32_t* r1, const std::int32_t* r2) {
        const std::int32_t ids[9] = {r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2]};
        std::uint32_t mask = 0;
        for (int k = 0; k < 9; ++k) mask |= cm[ids[k]];
        if (mask != 3) return;
        ZRange r = kEmptyRange;
        for (int k = 0; k < 9; ++k) merge(&r, cr[ids[k]]);
        const std::int32_t alo = std::max(r.glo, r.nlo) - 1;
        const std::int32_t ahi = std::min(r.ghi, r.nhi) + 1;
        if (alo > ahi) return;
        // The columns around, each with a cursor moving up with z.
        std::uint32_t cur[9], end[9];
        int n = 0;
        for (int k = 0; k < 9; ++k) {
          if (ids[k] == none) continue;
          cur[n] = cf[ids[k]];
          end[n++] = cf[ids[k] + 1];
        }
        for (std::uint32_t v = cf[q]; v < cf[q + 1]; ++v) {
          const std::int32_t z = zOf(v);
          if (z < alo) continue;
          if (z > ahi) break;
          std::uint32_t gs = 0, ts = 0;
          for (int j = 0; j < n; ++j) {
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
      });
}

void Voter::run(const VoxelGrid& g, int threads, WorkerPool* workers, Classifier* cls) {
  const int nt = threads > 1 && g.points() >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;  // ranges of whole rows
  splitRows(g, nch, &bounds_);
  // Relabelling while voting is exact: the sums read the per-voxel ground counts of the
  // classification (never rewritten), the labels written are per point.
  id_rows_.resize(static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) {  // here: a worker may first run a chunk in a later scan
    id_rows_[t].reserve(3 * (g.ny + 2));
  }
  workers->run(nt, nch, [&](int t, int c) { vote(g, t, c, cls); });
}

}  // namespace voxel
}  // namespace ground_filter
