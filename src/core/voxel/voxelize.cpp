#include "voxel/voxelize.h"

#include <algorithm>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "common/huge_pages.h"
#include "common/prefetch.h"
#include "common/radix_sort.h"
#include "voxel/avx2_passes.h"
#include "voxel/point_reads.h"

namespace ground_filter {
namespace voxel {

namespace {

// Sequential passes over the points prefetch this many points ahead (prefetchAhead(); TLS 5 M:
// 47 % of the key pass's samples had been on its load).
constexpr std::size_t kReadAhead = 32;

// Keys (of the coordinates relative to the min corner) and digit counts of the valid points among
// input [begin, end) (read from `pts`: the copy of scanBounds() or the input), written from slot
// `slot` on. SSE2 (every x86-64) or NEON (aarch64): one point per vector; the arithmetic is the
// scalar one lane by lane.
template <class O, bool kPacked, bool kAllValid, int kPasses, class Points>
void computeKeysT(const KeyJob job, const Points pts, std::size_t begin, std::size_t end,
                  std::size_t slot) {
  using V4 = typename O::V;
  const std::uint32_t dmask = (1u << job.digit) - 1;
  const int passes = kPasses > 0 ? kPasses : job.passes;
  const int digit = job.digit, shift_lo = job.shift_lo, slot_bits = job.slot_bits;
  const int shift_x = job.shift_x, shift_y = job.shift_y;
  std::uint32_t* const hist = job.hist;
  std::uint32_t* const hist1 = job.hist + (std::size_t{1} << digit);
  std::uint64_t* const keys = job.keys;
  const V4 vmin = O::v4LoadUnaligned(job.min);  // a member of the by-value job: not aligned
  std::size_t s = slot;
  for (std::size_t i = begin; i < end; ++i) {
    prefetchAhead(pts.address(i), kReadAhead * pts.stride());
    V4 p = pts.load(i);
    if (!kAllValid) {
      if (!O::v4Finite(p)) continue;
      job.index[s] = static_cast<std::uint32_t>(i);
    }
    p = O::v4Sub(p, vmin);
    std::uint32_t cell[4];
    O::v4Cells(p, job.inv_vs, job.last, cell);
    const std::uint64_t ix = cell[0], iy = cell[1], iz = cell[2];
    const std::uint64_t key = (ix << shift_x) | (iy << shift_y) | iz;
    std::uint64_t word;
    if (kPacked) {
      word = (key << slot_bits) | s;
      keys[s] = word;
    } else {
      word = key;
      keys[s] = key;
      job.order[s] = static_cast<std::uint32_t>(s);
    }
    ++s;
    word >>= shift_lo;
    ++hist[word & dmask];
    if (passes > 1) ++hist1[(word >> digit) & dmask];
    for (int q2 = 2; q2 < passes; ++q2) {
      ++hist[(static_cast<std::size_t>(q2) << digit) + ((word >> (q2 * digit)) & dmask)];
    }
  }
}

template <class O, class Points>
void computeKeys(const KeyJob& job, const Points& pts, std::size_t begin, std::size_t end,
                 std::size_t slot, bool avx2) {
  if (avx2 && job.packed && job.all_valid) {  // blocks of eight points, the rest below
    const std::size_t stop = computeKeysAvx2(job, pts.rows(), begin, end, slot);
    slot += stop - begin;
    begin = stop;
  }
  if (job.packed && job.all_valid && job.passes == 2) {  // the common case: one word a point
    computeKeysT<O, true, true, 2>(job, pts, begin, end, slot);
  } else if (job.packed && job.all_valid) {
    computeKeysT<O, true, true, 0>(job, pts, begin, end, slot);
  } else if (job.packed) {
    computeKeysT<O, true, false, 0>(job, pts, begin, end, slot);
  } else {
    computeKeysT<O, false, false, 0>(job, pts, begin, end, slot);
  }
}

}  // namespace

template <class O>
void Voxelizer::scanBounds(const CloudView& cloud, const DirectRead& direct, float* pts, bool avx2,
                           Chunk* ch) {
  // Takes the bounds and the number of the valid points; with `pts`, also copies x y z (w = 0)
  // of every input point there (one aligned vector a point for the key pass and the gather of
  // build()).
  using V4 = typename O::V;
  V4 lo = O::v4Splat(std::numeric_limits<float>::max());
  V4 hi = O::v4Splat(-std::numeric_limits<float>::max());
  std::size_t valid = 0;
  std::size_t first = ch->begin;   // first record of the scalar loop
  if (avx2 && direct.x && !pts) {  // blocks of eight records, the rest below
    alignas(16) float l[4], h[4];
    O::v4Store(l, lo);
    O::v4Store(h, hi);
    first = scanBoundsAvx2(direct, first, ch->end, l, h, &valid);
    lo = O::v4Load(l);
    hi = O::v4Load(h);
  }
  auto scan = [&](const auto& src) {
    for (std::size_t i = first; i < ch->end; ++i) {
      prefetchAhead(src.address(i), kReadAhead * src.stride());
      const V4 p = src.load(i);
      if (pts) O::v4Store(pts + 4 * i, p);
      if (!O::v4Finite(p)) continue;
      ++valid;
      lo = O::v4Min(p, lo);  // p < lo ? p : lo, as the scalar code did
      hi = O::v4Max(p, hi);
    }
  };
  if constexpr (kIsVector<O>) {
    if (direct.x) {
      scan(DirectPoints<O>{direct});
    } else {
      scan(FieldPoints<O>{cloud});
    }
  } else {
    scan(FieldPoints<O>{cloud});
  }
  ch->valid = valid;
  alignas(16) float l[4], h[4];
  O::v4Store(l, lo);
  O::v4Store(h, hi);
  for (int d = 0; d < 3; ++d) {
    ch->lo[d] = l[d];
    ch->hi[d] = h[d];
  }
}

bool Voxelizer::useVector() {
  return kHaveVec && (simd::allows(simd::Level::kSse) || simd::allows(simd::Level::kNeon));
}

void CellGrid::setup(const VoxelGroundFilterParams& p, std::uint64_t nx, std::uint64_t ny) {
  std::uint64_t border = 0;
  if (p.local_planes) {
    cell_vox = std::max<std::uint64_t>(1, std::llround(p.tile_size / p.voxel_size));
    constexpr std::uint64_t kMaxCells = std::uint64_t{1} << 22;  // memory cap for huge extents
    while (((nx + cell_vox - 1) / cell_vox + 2) * ((ny + cell_vox - 1) / cell_vox + 2) >
           kMaxCells) {
      cell_vox *= 2;
    }
    border = 1;
    ncx = (nx + cell_vox - 1) / cell_vox + 2;
    ncy = (ny + cell_vox - 1) / cell_vox + 2;
  } else {
    cell_vox = std::max(nx, ny);
    ncx = ncy = 1;
  }
  cell_of_x.resize(nx);
  cell_of_y.resize(ny);
  for (std::uint64_t i = 0; i < nx; ++i) {
    cell_of_x[i] = static_cast<std::uint32_t>((i / cell_vox + border) * ncy);
  }
  for (std::uint64_t i = 0; i < ny; ++i) {
    cell_of_y[i] = static_cast<std::uint32_t>(i / cell_vox + border);
  }
}

std::size_t Voxelizer::prepare(const CloudView& cloud, double vs, int threads, WorkerPool* pool,
                               const WorkingVolume* volume, VoxelGrid* g) {
  // The level of this scan, kept for build() (its point reads follow prepare()'s layout).
  vec_ = useVector();
  avx2_ = vec_ && useAvx2();
  const bool avx2 = avx2_;
  const std::size_t n_in = cloud.size();
  const int nt = threads > 1 && n_in >= kParallelMinPoints ? threads : 1;
  const int nch = nt == 1 ? 1 : 4 * nt;  // chunks of the input
  chunks_.resize(static_cast<std::size_t>(nch));
  for (int c = 0; c < nch; ++c) {
    chunks_[c].begin = n_in * c / nch;
    chunks_[c].end = n_in * (c + 1) / nch;
  }
  // Layout: x y z adjacent in every record are read with one 16-byte load a point, except the
  // records that have fewer than 16 bytes left from x on (the last one of packed x y z).
  // Plain (SIMD level portable) always reads the copy.
  direct_ = DirectRead();
  if (vec_ && cloud.xyzAdjacent()) {
    const std::size_t xo = cloud.xOffset(), step = cloud.stride(), bytes = n_in * step;
    direct_.x = cloud.data() + xo;
    direct_.step = step;
    direct_.vector_end =
        cloud.xyzFollowedByFloat() ? n_in : (bytes >= xo + 16 ? (bytes - xo - 16) / step + 1 : 0);
  }
  // Pass 1: bounds and number of the valid points of every chunk (and the copy, copied()).
  if (copied()) resizeScratch(&pxyz_, 4 * n_in);
  float* const copy = copied() ? pxyz_.data() : nullptr;
  withOps(vec_, [&](auto ops) {
    using O = decltype(ops);
    pool->run(nt, nch, [&](int, int c) { scanBounds<O>(cloud, direct_, copy, avx2, &chunks_[c]); });
  });
  std::size_t n = 0;
  float lo[3], hi[3];
  lo[0] = lo[1] = lo[2] = std::numeric_limits<float>::max();
  hi[0] = hi[1] = hi[2] = -std::numeric_limits<float>::max();
  for (Chunk& ch : chunks_) {
    ch.out = n;
    n += ch.valid;
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], ch.lo[d]);
      hi[d] = std::max(hi[d], ch.hi[d]);
    }
  }
  if (volume && n > 0 && !volume->containsBox(lo, hi)) return kOutside;
  g->all_valid = n == n_in;
  if (n == 0) return 0;
  const int key_bits = layoutKeys(lo, hi, vs, n, g);
  keyPass(vs, key_bits, n, nt, nch, pool, g);
  return n;
}

int Voxelizer::layoutKeys(const float lo[3], const float hi[3], double vs, std::size_t n,
                          VoxelGrid* g) {
  const float minx = lo[0], miny = lo[1], minz = lo[2];
  std::copy(lo, lo + 3, min_);
  std::copy(lo, lo + 3, g->min);
  const float maxx = hi[0], maxy = hi[1], maxz = hi[2];
  const std::uint64_t nx = static_cast<std::uint64_t>((static_cast<double>(maxx) - minx) / vs) + 1;
  const std::uint64_t ny = static_cast<std::uint64_t>((static_cast<double>(maxy) - miny) / vs) + 1;
  const std::uint64_t nz = static_cast<std::uint64_t>((static_cast<double>(maxz) - minz) / vs) + 1;
  const int bx = radixBitsFor(nx), by = radixBitsFor(ny), bz = radixBitsFor(nz);
  if (bx > kMaxAxisBits || by > kMaxAxisBits || bz > kMaxAxisBits) {
    std::ostringstream os;
    os << "cloud extent " << (maxx - minx) << " x " << (maxy - miny) << " x " << (maxz - minz)
       << " m is too large for voxel_size " << vs << " m (at most " << (1u << kMaxAxisBits)
       << " voxels per axis)";
    throw std::runtime_error(os.str());
  }
  g->nx = nx;
  g->ny = ny;
  g->nz = nz;
  g->shift_y = bz;
  g->shift_x = by + bz;
  g->mask_z = (std::uint64_t{1} << bz) - 1;
  g->mask_y = (std::uint64_t{1} << by) - 1;
  // Sorting (key << slot_bits | slot) words moves 8 bytes a point instead of 12 when key and
  // slot fit one word (slot_bits 32, fewer for keys over 32 bits: 5 M points need 23).
  g->slot_bits = std::min(32, 64 - (bx + by + bz));
  g->packed = n <= (std::uint64_t{1} << g->slot_bits);
  return bx + by + bz;
}

void Voxelizer::keyPass(double vs, int key_bits, std::size_t n, int nt, int nch, WorkerPool* pool,
                        VoxelGrid* g) {
  const bool avx2 = avx2_;
  float* const copy = copied() ? pxyz_.data() : nullptr;
  const float minx = min_[0], miny = min_[1], minz = min_[2];
  const std::uint64_t nx = g->nx, ny = g->ny, nz = g->nz;
  // Pass 2: voxel keys of the coordinates relative to the minimum (keeps float precision far
  // from the origin: UTM, TLS; build() forms the same relative coordinates again) and, on one
  // thread, the digit counts of every radix pass (as few passes as digits of at most
  // kRadixMaxDigitBits allow); several threads count per pass in sort().
  resizeScratch(&g->keys, n);
  if (!g->packed) resizeScratch(&g->order, n);
  if (!g->all_valid) resizeScratch(&g->point_index, n);
  plan_.lo = g->packed ? g->slot_bits : 0;
  plan_.passes = std::max(1, (key_bits + kRadixMaxDigitBits - 1) / kRadixMaxDigitBits);
  plan_.digit = std::max(1, (key_bits + plan_.passes - 1) / plan_.passes);
  // Digit counts of every pass, one histogram per thread (summed below).
  const std::size_t per = static_cast<std::size_t>(plan_.passes) << plan_.digit;
  hist_.assign(per * static_cast<std::size_t>(nt), 0);
  KeyJob job;
  job.keys = g->keys.data();
  job.order = g->order.data();
  job.index = g->point_index.data();
  job.hist = hist_.data();
  job.min[0] = minx;
  job.min[1] = miny;
  job.min[2] = minz;
  job.min[3] = 0.f;
  job.inv_vs = static_cast<float>(1.0 / vs);
  job.last[0] = static_cast<std::int32_t>(nx - 1);
  job.last[1] = static_cast<std::int32_t>(ny - 1);
  job.last[2] = static_cast<std::int32_t>(nz - 1);
  job.last[3] = 0;
  job.shift_x = g->shift_x;
  job.shift_y = g->shift_y;
  job.passes = plan_.passes;
  job.digit = plan_.digit;
  job.shift_lo = plan_.lo;
  job.packed = g->packed;
  job.slot_bits = g->slot_bits;
  job.all_valid = g->all_valid;
  pool->run(nt, nch, [&](int t, int c) {
    KeyJob own = job;
    own.hist = job.hist + per * static_cast<std::size_t>(t);
    const Chunk& ch = chunks_[c];
    withOps(vec_, [&](auto ops) {
      using O = decltype(ops);
      withPoints<O>(direct_, copy, [&](const auto& pts) {
        computeKeys<O>(own, pts, ch.begin, ch.end, ch.out, avx2);
      });
    });
  });
  for (int t = 1; t < nt; ++t) {
    const std::uint32_t* h = hist_.data() + per * static_cast<std::size_t>(t);
    for (std::size_t j = 0; j < per; ++j) hist_[j] += h[j];
  }
}

}  // namespace voxel
}  // namespace ground_filter
