#include "voxel/avx2_passes.h"

#include <algorithm>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>

#include <cstring>
#define GF_HAVE_AVX2 1
#define GF_TARGET_AVX2 __attribute__((target("avx2,popcnt")))
#else
#define GF_HAVE_AVX2 0
#endif

namespace ground_filter {
namespace voxel {

#if GF_HAVE_AVX2

namespace {

// Points read this many records ahead (as the SSE2 passes do).
constexpr std::size_t kReadAhead = 32;

GF_TARGET_AVX2 inline void prefetchBlock(const std::uint8_t* r, std::size_t step) {
  for (std::size_t b = 0; b < 8 * step; b += 64) {
    __builtin_prefetch(r + kReadAhead * step + b);
  }
}

// Records i and i + 4 of a block in the low and high half.
GF_TARGET_AVX2 inline __m256 pairOf(const std::uint8_t* r, std::size_t step, std::size_t k) {
  const __m128 a = _mm_loadu_ps(reinterpret_cast<const float*>(r + k * step));
  const __m128 b = _mm_loadu_ps(reinterpret_cast<const float*>(r + (k + 4) * step));
  return _mm256_insertf128_ps(_mm256_castps128_ps256(a), b, 1);
}

// Eight 32-bit or four 64-bit lanes from p (unaligned).
template <typename T>
GF_TARGET_AVX2 inline __m256i load(const T* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// Lanes 0, 1 and 2 of eight 16-byte records (`step` bytes apart) as three vectors, records in
// order (a 4 x 4 transpose per 128-bit half).
GF_TARGET_AVX2 inline void firstThreeLanes(const std::uint8_t* r, std::size_t step, __m256* l0,
                                           __m256* l1, __m256* l2) {
  const __m256 r0 = pairOf(r, step, 0), r1 = pairOf(r, step, 1);
  const __m256 r2 = pairOf(r, step, 2), r3 = pairOf(r, step, 3);
  const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpacklo_ps(r2, r3);
  const __m256 t2 = _mm256_unpackhi_ps(r0, r1), t3 = _mm256_unpackhi_ps(r2, r3);
  *l0 = _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(1, 0, 1, 0));
  *l1 = _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 2));
  *l2 = _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(1, 0, 1, 0));
}

// min(int((v - lo) * inv), last) per lane: the SSE2 key pass's float arithmetic (a subtraction,
// then a product: nothing to fuse) and its clamp (v >= lo, so the cell is >= 0).
GF_TARGET_AVX2 inline __m256i cellsOf(__m256 v, float lo, float inv, std::int32_t last) {
  const __m256 rel = _mm256_sub_ps(v, _mm256_set1_ps(lo));
  const __m256i q = _mm256_cvttps_epi32(_mm256_mul_ps(rel, _mm256_set1_ps(inv)));
  return _mm256_min_epi32(q, _mm256_set1_epi32(last));
}

// (ix << sx | iy << sy | iz) << slot_bits | slot of four points (cells: 32-bit lanes).
GF_TARGET_AVX2 inline __m256i wordsOf(__m128i ix, __m128i iy, __m128i iz, __m128i sx, __m128i sy,
                                      __m128i sb, __m256i slots) {
  const __m256i key =
      _mm256_or_si256(_mm256_or_si256(_mm256_sll_epi64(_mm256_cvtepu32_epi64(ix), sx),
                                      _mm256_sll_epi64(_mm256_cvtepu32_epi64(iy), sy)),
                      _mm256_cvtepu32_epi64(iz));
  return _mm256_or_si256(_mm256_sll_epi64(key, sb), slots);
}

// Digits of radix passes 0 and 1 of four words: digit 0 in the low, digit 1 in the high half.
GF_TARGET_AVX2 inline __m256i digitsOf(__m256i word, __m128i lo, __m128i digit, __m256i dmask) {
  const __m256i t = _mm256_srl_epi64(word, lo);
  const __m256i d0 = _mm256_and_si256(t, dmask);
  const __m256i d1 = _mm256_and_si256(_mm256_srl_epi64(t, digit), dmask);
  return _mm256_or_si256(d0, _mm256_slli_epi64(d1, 32));
}

GF_TARGET_AVX2 std::size_t keysAvx2(const KeyJob& job, const DirectRead& rows, std::size_t begin,
                                    std::size_t end, std::size_t slot) {
  end = std::min(end, rows.vector_end);
  const int passes = job.passes, digit = job.digit;
  const std::uint32_t dmask = (1u << digit) - 1;
  std::uint32_t* const hist = job.hist;
  std::uint32_t* const hist1 = job.hist + (std::size_t{1} << digit);
  std::uint64_t* const keys = job.keys;
  const std::size_t step = rows.step;
  const __m128i sx = _mm_cvtsi32_si128(job.shift_x), sy = _mm_cvtsi32_si128(job.shift_y);
  const __m128i sb = _mm_cvtsi32_si128(job.slot_bits), lo = _mm_cvtsi32_si128(job.shift_lo);
  const __m128i dg = _mm_cvtsi32_si128(digit);
  const __m256i dm = _mm256_set1_epi64x(dmask);
  const __m256i eight = _mm256_set1_epi64x(8);
  __m256i slots0 = _mm256_add_epi64(_mm256_set1_epi64x(static_cast<long long>(slot)),
                                    _mm256_set_epi64x(3, 2, 1, 0));
  __m256i slots1 = _mm256_add_epi64(slots0, _mm256_set1_epi64x(4));
  alignas(32) std::uint64_t dig[8];
  std::size_t i = begin, s = slot;
  for (; i + 8 <= end; i += 8, s += 8) {
    const std::uint8_t* r = rows.x + i * step;
    prefetchBlock(r, step);
    __m256 x, y, z;
    firstThreeLanes(r, step, &x, &y, &z);
    const __m256i cx = cellsOf(x, job.min[0], job.inv_vs, job.last[0]);
    const __m256i cy = cellsOf(y, job.min[1], job.inv_vs, job.last[1]);
    const __m256i cz = cellsOf(z, job.min[2], job.inv_vs, job.last[2]);
    const __m256i w0 = wordsOf(_mm256_castsi256_si128(cx), _mm256_castsi256_si128(cy),
                               _mm256_castsi256_si128(cz), sx, sy, sb, slots0);
    const __m256i w1 = wordsOf(_mm256_extracti128_si256(cx, 1), _mm256_extracti128_si256(cy, 1),
                               _mm256_extracti128_si256(cz, 1), sx, sy, sb, slots1);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + s), w0);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys + s + 4), w1);
    slots0 = _mm256_add_epi64(slots0, eight);
    slots1 = _mm256_add_epi64(slots1, eight);
    _mm256_store_si256(reinterpret_cast<__m256i*>(dig), digitsOf(w0, lo, dg, dm));
    _mm256_store_si256(reinterpret_cast<__m256i*>(dig + 4), digitsOf(w1, lo, dg, dm));
    for (int j = 0; j < 8; ++j) ++hist[static_cast<std::uint32_t>(dig[j])];
    if (passes > 1) {
      for (int j = 0; j < 8; ++j) ++hist1[dig[j] >> 32];
    }
    for (int q2 = 2; q2 < passes; ++q2) {
      for (int j = 0; j < 8; ++j) {
        const std::uint64_t word = keys[s + j] >> job.shift_lo;
        ++hist[(static_cast<std::size_t>(q2) << digit) + ((word >> (q2 * digit)) & dmask)];
      }
    }
  }
  return i;
}

GF_TARGET_AVX2 std::size_t boundsAvx2(const DirectRead& rows, std::size_t begin, std::size_t end,
                                      float lo_out[4], float hi_out[4], std::size_t* valid) {
  end = std::min(end, rows.vector_end);
  const std::size_t step = rows.step;
  // Four running minima and maxima (one per pair of records: no chain of dependent min/max);
  // min(p, lo) is p < lo ? p : lo, as in the SSE2 pass.
  __m256 lo[4], hi[4];
  for (int k = 0; k < 4; ++k) {
    lo[k] = _mm256_castps128_ps256(_mm_loadu_ps(lo_out));
    lo[k] = _mm256_insertf128_ps(lo[k], _mm_loadu_ps(lo_out), 1);
    hi[k] = _mm256_castps128_ps256(_mm_loadu_ps(hi_out));
    hi[k] = _mm256_insertf128_ps(hi[k], _mm_loadu_ps(hi_out), 1);
  }
  std::size_t n = 0, i = begin;
  const __m256 zero = _mm256_setzero_ps();
  for (; i + 8 <= end; i += 8) {
    const std::uint8_t* r = rows.x + i * step;
    prefetchBlock(r, step);
    __m256 p[4];
    int m[4];
    for (int k = 0; k < 4; ++k) {
      p[k] = pairOf(r, step, k);
      // x - x is 0 for finite x, NaN for NaN/Inf; lanes 0-2 of both halves (lane 3 is not x y z).
      m[k] = _mm256_movemask_ps(_mm256_cmp_ps(_mm256_sub_ps(p[k], p[k]), zero, _CMP_EQ_OQ));
    }
    if ((m[0] & m[1] & m[2] & m[3] & 0x77) == 0x77) {
      for (int k = 0; k < 4; ++k) {
        lo[k] = _mm256_min_ps(p[k], lo[k]);
        hi[k] = _mm256_max_ps(p[k], hi[k]);
      }
      n += 8;
      continue;
    }
    // A block with a non-finite point: record by record (pair k holds records k and k + 4).
    for (int k = 0; k < 4; ++k) {
      const int a = (m[k] & 7) == 7 ? -1 : 0, b = (m[k] & 0x70) == 0x70 ? -1 : 0;
      const __m256 keep = _mm256_castsi256_ps(_mm256_set_epi32(b, b, b, b, a, a, a, a));
      lo[k] = _mm256_blendv_ps(lo[k], _mm256_min_ps(p[k], lo[k]), keep);
      hi[k] = _mm256_blendv_ps(hi[k], _mm256_max_ps(p[k], hi[k]), keep);
      n += static_cast<std::size_t>(-a - b);
    }
  }
  // Both halves of the four accumulators into the caller's x y z (lane 3 is not used).
  __m256 l = _mm256_min_ps(_mm256_min_ps(lo[0], lo[1]), _mm256_min_ps(lo[2], lo[3]));
  __m256 h = _mm256_max_ps(_mm256_max_ps(hi[0], hi[1]), _mm256_max_ps(hi[2], hi[3]));
  _mm_storeu_ps(lo_out, _mm_min_ps(_mm256_castps256_ps128(l), _mm256_extractf128_ps(l, 1)));
  _mm_storeu_ps(hi_out, _mm_max_ps(_mm256_castps256_ps128(h), _mm256_extractf128_ps(h, 1)));
  *valid += n;
  return i;
}

GF_TARGET_AVX2 std::size_t centroids(const float* rec, const std::uint32_t* vstart, std::size_t nv,
                                     float* vx, float* vy, float* vz) {
  std::size_t v = 0;
  const __m256 one = _mm256_set1_ps(1.f);
  for (; v + 8 <= nv; v += 8) {
    // 1 / count (counts are below 2^31: the signed conversion is exact), as the scalar pass.
    const __m256i c0 = load(vstart + v);
    const __m256i c1 = load(vstart + v + 1);
    const __m256 inv = _mm256_div_ps(one, _mm256_cvtepi32_ps(_mm256_sub_epi32(c1, c0)));
    __m256 x, y, z;
    firstThreeLanes(reinterpret_cast<const std::uint8_t*>(rec + 4 * v), 16, &x, &y, &z);
    _mm256_storeu_ps(vx + v, _mm256_mul_ps(x, inv));
    _mm256_storeu_ps(vy + v, _mm256_mul_ps(y, inv));
    _mm256_storeu_ps(vz + v, _mm256_mul_ps(z, inv));
  }
  return v;
}

// Byte k of the result is bit k of `bits` (8 bits).
inline std::uint64_t bitsToBytes(std::uint32_t bits) {
  const std::uint64_t spread = (bits * 0x0101010101010101ull) & 0x8040201008040201ull;
  return ((spread + 0x7F7F7F7F7F7F7F7Full) >> 7) & 0x0101010101010101ull;
}

// Per 8-bit mask: the positions of its set bits, in order (the rest 0).
struct CompactTable {
  std::uint8_t idx[256][8];
};
constexpr CompactTable makeCompactTable() {
  CompactTable t{};
  for (int m = 0; m < 256; ++m) {
    int k = 0;
    for (int b = 0; b < 8; ++b) {
      if ((m >> b) & 1) t.idx[m][k++] = static_cast<std::uint8_t>(b);
    }
  }
  return t;
}
constexpr CompactTable kCompact = makeCompactTable();

// Appends the lanes of `ids` selected by `mask` to list[*n ...] (writes eight entries: the
// caller's buffer has room for them).
GF_TARGET_AVX2 inline void appendSelected(__m256i ids, int mask, std::uint32_t* list,
                                          std::size_t* n) {
  const __m256i perm =
      _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(kCompact.idx[mask])));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(list + *n),
                      _mm256_permutevar8x32_epi32(ids, perm));
  *n += static_cast<std::size_t>(__builtin_popcount(static_cast<unsigned>(mask)));
}

GF_TARGET_AVX2 std::size_t flagsOf(const VoxelFlagsJob& j, std::uint8_t* flags, VoxelLists* out) {
  const std::size_t nv = j.nv;
  if (nv == 0) return 0;
  voxelFlags(j, 0, 1, flags, out);  // no voxel before it
  const __m128i sy = _mm_cvtsi32_si128(j.shift_y);
  const __m256i mz = _mm256_set1_epi64x(static_cast<long long>(j.mask_z));
  const __m256i clearance = _mm256_set1_epi64x(kSeedClearanceVoxels);
  const __m256i below = _mm256_set1_epi32(static_cast<int>(j.min_pts) - 1);
  const __m256 thr = _mm256_set1_ps(j.flat_thr);
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i rec_idx =
      _mm256_mullo_epi32(lanes, _mm256_set1_epi32(static_cast<int>(j.rec_floats)));
  std::size_t v = 1;
  // Voxels v - 1 .. v + 8 exist; the lists have room for eight entries past their length (at
  // most v entries each, v + 8 < nv).
  for (; v + 8 < nv; v += 8) {
    int lowest = 0, clear = 0;
    for (int h = 0; h < 2; ++h) {  // four 64-bit keys a half
      const std::uint64_t* k = j.vkey + v + 4 * h;
      const __m256i key = load(k), prev = load(k - 1), next = load(k + 1);
      const __m256i col = _mm256_srl_epi64(key, sy);
      const __m256i same_prev = _mm256_cmpeq_epi64(_mm256_srl_epi64(prev, sy), col);
      const __m256i same_next = _mm256_cmpeq_epi64(_mm256_srl_epi64(next, sy), col);
      // z steps up to the next voxel: >= 1 in the same column (keys sorted and distinct); any
      // value in another one, where same_next decides.
      const __m256i dz = _mm256_sub_epi64(_mm256_and_si256(next, mz), _mm256_and_si256(key, mz));
      const __m256i free_above = _mm256_cmpgt_epi64(dz, clearance);
      lowest |= (~_mm256_movemask_pd(_mm256_castsi256_pd(same_prev)) & 0xF) << (4 * h);
      clear |= ((~_mm256_movemask_pd(_mm256_castsi256_pd(same_next)) & 0xF) |
                _mm256_movemask_pd(_mm256_castsi256_pd(free_above)))
               << (4 * h);
    }
    // Counts are below 2^31 and min_pts at most 1000: signed compares are exact.
    const __m256i c0 = load(j.vstart + v);
    const __m256i c1 = load(j.vstart + v + 1);
    const __m256i dense = _mm256_cmpgt_epi32(_mm256_sub_epi32(c1, c0), below);
    const __m256 zr = _mm256_i32gather_ps(j.rec + j.rec_floats * v + 3, rec_idx, 4);
    const __m256 thin = _mm256_cmp_ps(zr, thr, _CMP_LT_OQ);  // zrange < thr (false for NaN)
    const int dense_bits = _mm256_movemask_ps(_mm256_castsi256_ps(dense));
    const int flat = dense_bits & _mm256_movemask_ps(thin);
    const int seed = (flat | (~dense_bits & 0xFF)) & lowest & clear;
    const std::uint64_t bytes = bitsToBytes(static_cast<std::uint32_t>(flat)) * kFlat |
                                bitsToBytes(static_cast<std::uint32_t>(seed)) * kSeed;
    std::memcpy(flags + v, &bytes, sizeof(bytes));
    const __m256i ids = _mm256_add_epi32(lanes, _mm256_set1_epi32(static_cast<int>(v)));
    appendSelected(ids, lowest, out->col_first, &out->ncol);
    appendSelected(ids, j.local ? flat & seed : flat, out->flat, &out->nflat);
    appendSelected(ids, seed, out->seeds, &out->nseed);
  }
  return v;
}

}  // namespace

bool cpuHasAvx2() { return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt"); }

std::size_t computeKeysAvx2(const KeyJob& job, const DirectRead& rows, std::size_t begin,
                            std::size_t end, std::size_t slot) {
  return keysAvx2(job, rows, begin, end, slot);
}

std::size_t scanBoundsAvx2(const DirectRead& rows, std::size_t begin, std::size_t end, float lo[4],
                           float hi[4], std::size_t* valid) {
  return boundsAvx2(rows, begin, end, lo, hi, valid);
}

std::size_t centroidsAvx2(const float* rec, const std::uint32_t* vstart, std::size_t nv, float* vx,
                          float* vy, float* vz) {
  return centroids(rec, vstart, nv, vx, vy, vz);
}

std::size_t voxelFlagsAvx2(const VoxelFlagsJob& j, std::uint8_t* flags, VoxelLists* out) {
  return flagsOf(j, flags, out);
}

#else  // no AVX2 build (aarch64: Jetson): never called, cpuHasAvx2() is false

bool cpuHasAvx2() { return false; }

std::size_t computeKeysAvx2(const KeyJob&, const DirectRead&, std::size_t begin, std::size_t,
                            std::size_t) {
  return begin;
}

std::size_t scanBoundsAvx2(const DirectRead&, std::size_t begin, std::size_t, float*, float*,
                           std::size_t*) {
  return begin;
}

std::size_t centroidsAvx2(const float*, const std::uint32_t*, std::size_t, float*, float*, float*) {
  return 0;
}

std::size_t voxelFlagsAvx2(const VoxelFlagsJob&, std::uint8_t*, VoxelLists*) { return 0; }

#endif

}  // namespace voxel
}  // namespace ground_filter
