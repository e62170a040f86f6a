#include "voxel/voxelize.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "common/huge_pages.h"
#include "common/prefetch.h"
#include "common/radix_sort.h"
#include "voxel/avx2_passes.h"

namespace ground_filter {
namespace voxel {

namespace {

// Four floats x y z 0 of one point, two implementations with the same results lane by lane,
// chosen per scan (Voxelizer::prepare()): Sse (SSE2, every x86-64, SIMD level sse and up) and
// Plain (plain floats: SIMD level portable, and what aarch64 runs). Each one's operations are
// static functions; the passes below are templates on the implementation (O).
struct Plain {
  struct V {
    float v[4];
  };
  static V v4Load(const float* p) { return V{{p[0], p[1], p[2], p[3]}}; }
  static V v4LoadUnaligned(const float* p) { return v4Load(p); }
  static void v4Store(float* p, V a) {
    for (int k = 0; k < 4; ++k) p[k] = a.v[k];
  }
  static V v4Set(float x, float y, float z) { return V{{x, y, z, 0.f}}; }
  static V v4Splat(float a) { return V{{a, a, a, a}}; }
  static V v4Sub(V a, V b) {
    for (int k = 0; k < 4; ++k) a.v[k] -= b.v[k];
    return a;
  }
  static V v4Min(V a, V b) {
    for (int k = 0; k < 4; ++k) a.v[k] = a.v[k] < b.v[k] ? a.v[k] : b.v[k];
    return a;
  }
  static V v4Max(V a, V b) {
    for (int k = 0; k < 4; ++k) a.v[k] = a.v[k] > b.v[k] ? a.v[k] : b.v[k];
    return a;
  }
  static V v4Add(V a, V b) {
    for (int k = 0; k < 4; ++k) a.v[k] += b.v[k];
    return a;
  }
  static void v4StoreUnaligned(float* p, V a) { v4Store(p, a); }
  static V v4WithNegZ(V p) { return V{{p.v[0], p.v[1], p.v[2], -p.v[2]}}; }
  static V v4SumsAndRange(V s, V h) { return V{{s.v[0], s.v[1], s.v[2], h.v[3] + h.v[2]}}; }
  static bool v4Finite(V p) {
    return (p.v[0] - p.v[0]) + (p.v[1] - p.v[1]) + (p.v[2] - p.v[2]) == 0.f;
  }
  static V v4ZeroIf(V s, bool restart) { return restart ? v4Splat(0.f) : s; }
  static V v4LowestIf(V h, bool restart) {
    return restart ? v4Splat(-std::numeric_limits<float>::infinity()) : h;
  }
  static void v4Cells(V p, float inv, const std::int32_t* last, std::uint32_t* out) {
    for (int k = 0; k < 3; ++k) {
      out[k] =
          std::min(static_cast<std::uint32_t>(p.v[k] * inv), static_cast<std::uint32_t>(last[k]));
    }
  }
};

#if defined(__SSE2__)
struct Sse {
  using V = __m128;
  static V v4Load(const float* p) { return _mm_load_ps(p); }  // p 16-byte aligned
  static V v4LoadUnaligned(const float* p) { return _mm_loadu_ps(p); }
  static void v4Store(float* p, V v) { _mm_store_ps(p, v); }
  static V v4Set(float x, float y, float z) { return _mm_set_ps(0.f, z, y, x); }
  static V v4Splat(float a) { return _mm_set1_ps(a); }
  static V v4Sub(V a, V b) { return _mm_sub_ps(a, b); }
  static V v4Min(V a, V b) { return _mm_min_ps(a, b); }  // a < b ? a : b
  static V v4Max(V a, V b) { return _mm_max_ps(a, b); }  // a > b ? a : b
  static V v4Add(V a, V b) { return _mm_add_ps(a, b); }
  static void v4StoreUnaligned(float* p, V v) { _mm_storeu_ps(p, v); }
  // (x, y, z, -z) of (x, y, z, w): negation is exact.
  static V v4WithNegZ(V p) {
    const V sign =
        _mm_castsi128_ps(_mm_set_epi32(std::numeric_limits<std::int32_t>::min(), 0, 0, 0));
    return _mm_xor_ps(_mm_shuffle_ps(p, p, _MM_SHUFFLE(2, 2, 1, 0)), sign);
  }
  // (s0, s1, s2, h2 + h3): with h2 = max z and h3 = -min z, lane 3 is max z - min z exactly.
  static V v4SumsAndRange(V s, V h) {
    const V r = _mm_add_ps(h, _mm_shuffle_ps(h, h, _MM_SHUFFLE(2, 2, 2, 2)));  // lane 3: h3 + h2
    const V t = _mm_shuffle_ps(s, r, _MM_SHUFFLE(3, 3, 2, 2));                 // s2 s2 r3 r3
    return _mm_shuffle_ps(s, t, _MM_SHUFFLE(2, 0, 1, 0));
  }
  // x - x is 0 for finite x and NaN for NaN/Inf: one test for all lanes.
  static bool v4Finite(V p) {
    return _mm_movemask_ps(_mm_cmpeq_ps(_mm_sub_ps(p, p), _mm_setzero_ps())) == 0xF;
  }
  // restart ? +0 : s, and restart ? -inf : h, as bit masks (no multiply or add in the dependency
  // chains of the gather's running sums and maxima).
  static V v4ZeroIf(V s, bool restart) {
    alignas(16) static const std::uint32_t kMask[2][4] = {{~0u, ~0u, ~0u, ~0u}, {0, 0, 0, 0}};
    return _mm_and_ps(s, _mm_load_ps(reinterpret_cast<const float*>(kMask[restart])));
  }
  static V v4LowestIf(V h, bool restart) {
    alignas(16) static const std::uint32_t kNegInf[2][4] = {
        {0, 0, 0, 0}, {0xFF800000u, 0xFF800000u, 0xFF800000u, 0xFF800000u}};
    return _mm_or_ps(v4ZeroIf(h, restart),
                     _mm_load_ps(reinterpret_cast<const float*>(kNegInf[restart])));
  }
  // min(int(p * inv), last) per lane (p >= 0 and below 2^22: the axis checks of prepare()).
  static void v4Cells(V p, float inv, const std::int32_t* last, std::uint32_t* out) {
    const __m128i vlast = _mm_loadu_si128(reinterpret_cast<const __m128i*>(last));
    __m128i q = _mm_cvttps_epi32(_mm_mul_ps(p, _mm_set1_ps(inv)));
    const __m128i over = _mm_cmpgt_epi32(q, vlast);
    q = _mm_or_si128(_mm_and_si128(over, vlast), _mm_andnot_si128(over, q));
    out[0] = static_cast<std::uint32_t>(_mm_cvtsi128_si32(q));
    out[1] = static_cast<std::uint32_t>(_mm_cvtsi128_si32(_mm_srli_si128(q, 4)));
    out[2] = static_cast<std::uint32_t>(_mm_cvtsi128_si32(_mm_srli_si128(q, 8)));
  }
};
constexpr bool kHaveSse = true;
#else
using Sse = Plain;  // never chosen (kHaveSse): Voxelizer::useSse() is false
constexpr bool kHaveSse = false;
#endif

// Calls f(O{}) with the implementation of the V4 operations: Sse or Plain.
template <class F>
void withOps(bool sse, F&& f) {
  if (kHaveSse && sse) {
    f(Sse{});
  } else {
    f(Plain{});
  }
}

// Where the key pass and the gather read a point's x y z (lane 3 zero): the aligned copy made
// by the first pass, or the input records themselves (x y z adjacent, records of at most 16
// bytes, SSE2: no copy to write and read back; Voxelizer::prepare()).
template <class O>
struct CopyPoints {
  using V4 = typename O::V;
  const float* xyz0;  // x y z 0 per input point, 16-byte aligned
  V4 load(std::size_t i) const { return O::v4Load(xyz0 + 4 * i); }
  V4 loadXyz(std::size_t i) const { return load(i); }
  const void* address(std::size_t i) const { return xyz0 + 4 * i; }
  std::size_t stride() const { return 4 * sizeof(float); }
  // The copy as records for the AVX2 passes: every one has 16 bytes.
  DirectRead rows() const {
    return DirectRead{reinterpret_cast<const std::uint8_t*>(xyz0), 16, ~std::size_t{0}};
  }
};
// Any layout: three scalar reads a record (first pass only; the other passes read the copy).
template <class O>
struct FieldPoints {
  using V4 = typename O::V;
  CloudView view;
  V4 load(std::size_t i) const { return O::v4Set(view.x(i), view.y(i), view.z(i)); }
  const void* address(std::size_t i) const { return view.data() + i * view.stride(); }
  std::size_t stride() const { return view.stride(); }
};
#if defined(__SSE2__)
struct DirectPoints {
  Voxelizer::DirectRead d;
  __m128 load(std::size_t i) const {
    const std::uint8_t* r = d.x + i * d.step;
    if (i < d.vector_end) {  // taken for all but the last record of packed x y z clouds
      return _mm_and_ps(_mm_loadu_ps(reinterpret_cast<const float*>(r)),
                        _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1)));
    }
    float c[3];
    std::memcpy(c, r, sizeof(c));
    return Sse::v4Set(c[0], c[1], c[2]);
  }
  // x y z and a fourth lane of any value (the gather replaces it: no mask).
  __m128 loadXyz(std::size_t i) const {
    return i < d.vector_end ? _mm_loadu_ps(reinterpret_cast<const float*>(d.x + i * d.step))
                            : load(i);
  }
  const void* address(std::size_t i) const { return d.x + i * d.step; }
  std::size_t stride() const { return d.step; }
  DirectRead rows() const { return d; }
};
#endif

// Calls f with where the key pass and the gather read the points: `copy` (x y z 0 per point),
// or, Sse only, the input records in place when there is no copy (prepare() makes the copy
// for every layout when it runs Plain).
template <class O, class F>
void withPoints(const Voxelizer::DirectRead& direct, const float* copy, F&& f) {
#if defined(__SSE2__)
  if constexpr (std::is_same<O, Sse>::value) {
    if (!copy) {
      f(DirectPoints{direct});
      return;
    }
  }
#else
  (void)direct;
#endif
  f(CopyPoints<O>{copy});
}

}  // namespace

namespace {

// Floats of gatherRuns()'s record per voxel: sums of x, y, z and max z - min z.
constexpr std::size_t kRunRecord = 4;

// Sequential passes over the points prefetch this many points ahead (prefetchAhead(); TLS 5 M:
// 47 % of the key pass's samples had been on its load).
constexpr std::size_t kReadAhead = 32;

// Keys (of the coordinates relative to the min corner) and digit counts of the valid points among
// input [begin, end) (read from `pts`: the copy of scanBounds() or the input), written from slot
// `slot` on. SSE2 (every x86-64): one point per vector; the arithmetic is the scalar one lane by
// lane.
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
#if defined(__SSE2__)
  if constexpr (std::is_same<O, Sse>::value) {
    if (direct.x) {
      scan(DirectPoints{direct});
    } else {
      scan(FieldPoints<O>{cloud});
    }
  } else {
    scan(FieldPoints<O>{cloud});
  }
#else
  scan(FieldPoints<O>{cloud});
#endif
  ch->valid = valid;
  alignas(16) float l[4], h[4];
  O::v4Store(l, lo);
  O::v4Store(h, hi);
  for (int d = 0; d < 3; ++d) {
    ch->lo[d] = l[d];
    ch->hi[d] = h[d];
  }
}

bool Voxelizer::useSse() { return kHaveSse && simd::allows(simd::Level::kSse); }

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
  sse_ = useSse();
  avx2_ = sse_ && useAvx2();
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
  // Plain (SIMD level portable, aarch64) always reads the copy, as aarch64 does.
  direct_ = DirectRead();
#if defined(__SSE2__)
  if (sse_ && cloud.xyzAdjacent()) {
    const std::size_t xo = cloud.xOffset(), step = cloud.stride(), bytes = n_in * step;
    direct_.x = cloud.data() + xo;
    direct_.step = step;
    direct_.vector_end =
        cloud.xyzFollowedByFloat() ? n_in : (bytes >= xo + 16 ? (bytes - xo - 16) / step + 1 : 0);
  }
#endif
  // Pass 1: bounds and number of the valid points of every chunk (and the copy, copied()).
  if (copied()) resizeScratch(&pxyz_, 4 * n_in);
  float* const copy = copied() ? pxyz_.data() : nullptr;
  withOps(sse_, [&](auto ops) {
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
  const float minx = lo[0], miny = lo[1], minz = lo[2];
  std::copy(lo, lo + 3, min_);
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

  // Pass 2: voxel keys of the coordinates relative to the minimum (keeps float precision far
  // from the origin: UTM, TLS; build() forms the same relative coordinates again) and, on one
  // thread, the digit counts of every radix pass (as few passes as digits of at most
  // kRadixMaxDigitBits allow); several threads count per pass in sort().
  resizeScratch(&g->keys, n);
  if (!g->packed) resizeScratch(&g->order, n);
  if (!g->all_valid) resizeScratch(&g->point_index, n);
  const int key_bits = bx + by + bz;
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
    withOps(sse_, [&](auto ops) {
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
  return n;
}

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
  const bool avx2 = avx2_;  // prepare()'s choice for this scan
  const std::size_t n = g->keys.size();
  const int nt = threads > 1 && n >= parallel_min_points_ ? threads : 1;
  sort(nt, pool, g);
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
  cells->used.assign(cells->count(), 0);
  const std::uint64_t* k = g->keys.data();
  const std::uint32_t* o = g->order.data();
  const bool av = g->all_valid;
  const std::uint32_t* pidx = g->point_index.data();
  float* xyz_out = g->sxyz.data();
  resizeScratch(&g->pvox, n);
  std::uint32_t* pv = g->pvox.data();
  std::uint64_t* vk = g->vkey.data();
  std::uint32_t* vs = g->vstart.data();
  std::uint8_t* used = cells->used.data();
  const std::uint32_t* cxt = cells->cell_of_x.data();
  const std::uint32_t* cyt = cells->cell_of_y.data();
  const std::uint32_t min_pts = static_cast<std::uint32_t>(p.min_points_per_voxel);
  const float flat_thr = static_cast<float>(p.flatness_threshold);
  const bool pk = g->packed;
  const int slot_bits = g->slot_bits;
  const int low = pk ? slot_bits : 0;
  const std::uint64_t slot_mask = (std::uint64_t{1} << slot_bits) - 1;
  const int sy_ = g->shift_y, sx_ = g->shift_x;
  const bool local = p.local_planes;
  const std::uint64_t my = g->mask_y, mz = g->mask_z;
  // Passes without a branch per point or voxel. Pass 1 (gatherRuns(), specialised for the key
  // layout): coordinates in key order, voxels, running sums and z ranges.
  // Fields in RunJob's order: inputs, point outputs, voxel outputs, key layout, min corner.
  RunJob job = {k, o, pidx, xyz_out, pv, vk, vs, vrec_.data(), slot_mask, low, {}};
  std::copy(min_, min_ + 3, job.min);
  job.min[3] = -min_[2];
  std::size_t nv = 0;
  withOps(sse_, [&](auto ops) {
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
