#include "voxel/vote.h"

#include <algorithm>

#include "voxel/column_sweep.h"

namespace ground_filter {
namespace voxel {

void Voter::votedRanges(const VoxelGrid& g, const Classifier& cls, int t, int range) {
  // A voxel's vote can differ from its own points' labels only when its neighbourhood holds both
  // ground and non-ground points: only voxels within one z step of a ground voxel and of a
  // non-ground voxel of their 3 x 3 columns are voted. Per column: z ranges of the voxels with
  // ground and with non-ground points (classification), dilated over y into dense rows, then
  // over x from the rows x - 1, x, x + 1.
  const ZRange* cr = cls.col_range.data();
  const std::uint64_t* ck = g.col_key.data();
  const std::uint64_t y_mask = g.mask_y;
  std::int32_t* alo = alo_.data();
  std::int32_t* ahi = ahi_.data();
  sweepColumns(
      g, bounds_[range], bounds_[range + 1], &range_rows_[t], kEmptyRange,
      [&](ZRange* row, std::size_t q) {
        const std::uint64_t y = ck[q] & y_mask;
        for (std::uint64_t j = y; j <= y + 2; ++j) {
          row[j].glo = std::min(row[j].glo, cr[q].glo);
          row[j].ghi = std::max(row[j].ghi, cr[q].ghi);
          row[j].nlo = std::min(row[j].nlo, cr[q].nlo);
          row[j].nhi = std::max(row[j].nhi, cr[q].nhi);
        }
      },
      [&](ZRange* row, std::size_t q) {
        const std::uint64_t y = ck[q] & y_mask;
        row[y] = row[y + 1] = row[y + 2] = kEmptyRange;
      },
      [&](std::size_t q, const ZRange* r0, const ZRange* r1, const ZRange* r2) {
        const std::int32_t lo = std::min({r0[1].glo, r1[1].glo, r2[1].glo});
        const std::int32_t hi = std::max({r0[1].ghi, r1[1].ghi, r2[1].ghi});
        const std::int32_t lo2 = std::min({r0[1].nlo, r1[1].nlo, r2[1].nlo});
        const std::int32_t hi2 = std::max({r0[1].nhi, r1[1].nhi, r2[1].nhi});
        alo[q] = std::max(lo, lo2) - 1;
        ahi[q] = std::min(hi, hi2) + 1;
      });
}

void Voter::buildColumn(const VoxelGrid& g, const Classifier& cls, std::size_t c) {
  built_[c] = 1;
  const ColInfo& ci = col_info_[c];
  if (ci.ext < 0) return;
  const std::uint64_t* vk = g.vkey.data();
  const std::uint32_t* vs = g.vstart.data();
  const std::uint32_t* vg = cls.voxel_ground.data();
  const std::uint64_t mz = g.mask_z;
  std::uint32_t* q = pre_.data() + 2 * ci.pool;
  std::uint32_t sg = 0, sn = 0;
  q[0] = q[1] = 0;
  std::uint32_t v = ci.first;
  for (std::int32_t j = 0; j < ci.ext; ++j) {
    if (v < ci.end && static_cast<std::int32_t>(vk[v] & mz) == ci.base + j) {
      sg += vg[v];
      sn += vs[v + 1] - vs[v];
      ++v;
    }
    q[2 * j + 2] = sg;
    q[2 * j + 3] = sn;
  }
}

void Voter::sums(const VoxelGrid& g, const Classifier& cls, int t, int range, bool lazy) {
  const std::size_t ncol = g.columns();
  const std::uint64_t* vk = g.vkey.data();
  const std::uint32_t* vs = g.vstart.data();
  const std::uint32_t* vg = cls.voxel_ground.data();
  const std::uint32_t* cf = g.col_first.data();
  const std::uint64_t mz = g.mask_z;
  const std::uint64_t* ck = g.col_key.data();
  const std::uint64_t y_mask = g.mask_y;
  const std::int32_t* alo = alo_.data();
  const std::int32_t* ahi = ahi_.data();
  const ColInfo* ci = col_info_.data();
  const std::uint32_t* pp = pre_.data();
  const std::uint8_t* built = built_.data();
  std::uint32_t* sgv = sum_g_.data();
  std::uint32_t* snv = sum_n_.data();
  // Rows of column ids (the empty sentinel `ncol` where there is none).
  const std::int32_t none = static_cast<std::int32_t>(ncol);
  sweepColumns(
      g, bounds_[range], bounds_[range + 1], &id_rows_[t], none,
      [&](std::int32_t* row, std::size_t q) {
        row[(ck[q] & y_mask) + 1] = static_cast<std::int32_t>(q);
      },
      [&](std::int32_t* row, std::size_t q) { row[(ck[q] & y_mask) + 1] = none; },
      [&](std::size_t q, const std::int32_t* r0, const std::int32_t* r1, const std::int32_t* r2) {
        if (alo[q] > ahi[q]) return;
        const std::int32_t ids[9] = {r0[0], r0[1], r0[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2]};
        const ColInfo* nb[9];
        for (int k = 0; k < 9; ++k) {
          if (lazy && !built[ids[k]]) buildColumn(g, cls, static_cast<std::size_t>(ids[k]));
          nb[k] = ci + ids[k];
        }
        for (std::uint32_t v = cf[q]; v < cf[q + 1]; ++v) {
          const std::int32_t z = static_cast<std::int32_t>(vk[v] & mz);
          if (z < alo[q]) continue;
          if (z > ahi[q]) break;
          std::uint32_t gs = 0, ts = 0;
          for (int k = 0; k < 9; ++k) {
            const ColInfo& d = *nb[k];
            if (d.ext >= 0) {
              const std::int32_t lo = std::min(std::max(z - 1 - d.base, 0), d.ext);
              const std::int32_t hi = std::min(std::max(z + 2 - d.base, lo), d.ext);
              const std::uint32_t* pq = pp + 2 * d.pool;
              gs += pq[2 * hi] - pq[2 * lo];
              ts += pq[2 * hi + 1] - pq[2 * lo + 1];
            } else {
              for (std::uint32_t u = d.first; u < d.end; ++u) {
                const std::int32_t dz = static_cast<std::int32_t>(vk[u] & mz) - z;
                if (dz >= -1 && dz <= 1) {
                  gs += vg[u];
                  ts += vs[u + 1] - vs[u];
                }
              }
            }
          }
          sgv[v] = gs;
          snv[v] = ts;
        }
      });
}

void Voter::run(const VoxelGrid& g, int threads, WorkerPool* workers, Classifier* cls) {
  const std::size_t nv = g.voxels();
  const std::size_t ncol = g.columns();
  const std::uint64_t* vk = g.vkey.data();
  const std::uint32_t* vs = g.vstart.data();
  const std::uint32_t* cf = g.col_first.data();
  const std::uint64_t mz = g.mask_z;
  const int nt = threads > 1 && g.points() >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;  // ranges of whole rows
  splitRows(g, nch, &bounds_);
  range_rows_.resize(static_cast<std::size_t>(nt));
  id_rows_.resize(static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) {  // here: a worker may first run a chunk in a later scan
    range_rows_[t].reserve(3 * (g.ny + 2));
    id_rows_[t].reserve(3 * (g.ny + 2));
  }
  alo_.resize(ncol);
  ahi_.resize(ncol);
  // Per column, prefix sums of (ground, all) points over z from its lowest voxel - 1 to its
  // highest + 1: the sums over a z window of three are two loads. Columns with long empty
  // stretches (tree canopy over ground) are scanned instead. Column `ncol` is an empty sentinel.
  col_info_.resize(ncol + 1);
  ColInfo* ci = col_info_.data();
  std::size_t pool = 0;
  for (std::size_t c = 0; c < ncol; ++c) {
    const std::int32_t z0 = static_cast<std::int32_t>(vk[cf[c]] & mz);
    const std::int32_t z1 = static_cast<std::int32_t>(vk[cf[c + 1] - 1] & mz);
    const std::uint32_t cnt = cf[c + 1] - cf[c];
    ci[c].base = z0 - 1;
    ci[c].pool = static_cast<std::uint32_t>(pool);
    ci[c].first = cf[c];
    ci[c].end = cf[c + 1];
    if (static_cast<std::uint32_t>(z1 - z0) <= 4 * cnt + 8) {
      ci[c].ext = z1 - z0 + 3;
      pool += static_cast<std::size_t>(ci[c].ext) + 1;
    } else {
      ci[c].ext = -1;
    }
  }
  ci[ncol] = ColInfo{0, 0, static_cast<std::uint32_t>(pool), 0, 0};
  pool += 1;
  pre_.resize(2 * pool);
  built_.assign(ncol + 1, 0);
  sum_g_.resize(nv);
  sum_n_.resize(nv);
  const std::int32_t* alo = alo_.data();
  const std::int32_t* ahi = ahi_.data();
  std::uint8_t* out = cls->ground.data();
  const std::uint32_t* sgv = sum_g_.data();
  const std::uint32_t* snv = sum_n_.data();
  // Relabel after all sums (the sums read the classification only).
  auto relabel = [&](std::size_t c0, std::size_t c1) {
    for (std::size_t c = c0; c < c1; ++c) {
      if (alo[c] > ahi[c]) continue;
      for (std::uint32_t v = cf[c]; v < cf[c + 1]; ++v) {
        const std::int32_t z = static_cast<std::int32_t>(vk[v] & mz);
        if (z < alo[c]) continue;
        if (z > ahi[c]) break;
        if (2 * sgv[v] == snv[v]) continue;  // tie: keep the per-point labels
        const std::uint8_t label = 2 * sgv[v] > snv[v] ? 1 : 0;
        for (std::uint32_t k = vs[v]; k < vs[v + 1]; ++k) out[k] = label;
      }
    }
  };
  if (nt == 1) {
    // Prefix sums built on first use: only the neighbours of voted voxels need them.
    votedRanges(g, *cls, 0, 0);
    sums(g, *cls, 0, 0, true);
    relabel(0, ncol);
    return;
  }
  workers->run(nt, nch, [&](int t, int c) {
    votedRanges(g, *cls, t, c);
    for (std::size_t q = (ncol + 1) * c / nch; q < (ncol + 1) * (c + 1) / nch; ++q) {
      buildColumn(g, *cls, q);
    }
  });
  workers->run(nt, nch, [&](int t, int c) { sums(g, *cls, t, c, false); });
  workers->run(nt, nch, [&](int, int c) { relabel(bounds_[c], bounds_[c + 1]); });
}

}  // namespace voxel
}  // namespace ground_filter
