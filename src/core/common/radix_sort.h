#ifndef GROUND_FILTER_SRC_CORE_COMMON_RADIX_SORT_H
#define GROUND_FILTER_SRC_CORE_COMMON_RADIX_SORT_H

// The one sort of the core: an LSD radix sort of 64-bit keys (the voxel keys of the voxel filter,
// the grid-column and tile keys of the normal filter).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/huge_pages.h"
#include "common/prefetch.h"

namespace ground_filter {

/// Radix digits of at most this many bits: at most 64 k buckets (256 KB of counts, in L2). 16,
/// not 15: keys of 31-32 bits (a 5 M-point TLS scan) take two passes instead of three (TLS 5 M
/// 153-155 -> 143-144 ms on the Intel VM, docs/voxel_method.md).
constexpr int kRadixMaxDigitBits = 16;

/// Keys ahead of a scatter pass's sequential reads that it prefetches (prefetchAhead()).
constexpr std::size_t kRadixReadAhead = 64;

/// \brief Bits needed for the values 0 .. max_value (at least 1).
inline int radixBitsFor(std::uint64_t max_value) {
  int bits = 1;
  while (bits < 64 && (max_value >> bits) != 0) ++bits;
  return bits;
}

/// \brief Scatter passes of a stable LSD radix sort of `a` (with `b` alongside when not null)
///        over the bits [lo, lo + passes * digit); `hist` holds the digit counts of every pass
///        (passes << digit entries, counted by the caller, e.g. while it wrote the keys) and is
///        overwritten. Passes whose digit is the same for every key are skipped.
template <typename B>
void radixScatter(int lo, int passes, int digit, std::uint32_t* hist, std::vector<std::uint64_t>* a,
                  std::vector<std::uint64_t>* a_tmp, std::vector<B>* b, std::vector<B>* b_tmp) {
  const std::size_t n = a->size();
  if (n == 0) return;
  const std::uint32_t mask = (1u << digit) - 1;
  resizeScratch(a_tmp, n);
  if (b) resizeScratch(b_tmp, n);
  for (int q = 0; q < passes; ++q) {
    const int shift = lo + q * digit;
    std::uint32_t* h = hist + (static_cast<std::size_t>(q) << digit);
    if (h[((*a)[0] >> shift) & mask] == n) continue;  // every key has this digit
    std::uint32_t sum = 0;
    for (std::uint32_t j = 0; j <= mask; ++j) {
      const std::uint32_t cnt = h[j];
      h[j] = sum;
      sum += cnt;
    }
    const std::uint64_t* k = a->data();
    std::uint64_t* kt = a_tmp->data();
    if (b) {
      const B* o = b->data();
      B* ot = b_tmp->data();
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t dst = h[(k[i] >> shift) & mask]++;
        kt[dst] = k[i];
        ot[dst] = o[i];
      }
      b->swap(*b_tmp);
    } else {
      for (std::size_t i = 0; i < n; ++i) {
        prefetchAhead(k + i, 8 * kRadixReadAhead);
        kt[h[(k[i] >> shift) & mask]++] = k[i];
      }
    }
    a->swap(*a_tmp);
  }
}

/// \brief radixScatter() on several threads, for arrays much larger than the cache: every pass
///        splits `a` (and `b` alongside when not null) into `blocks` equal blocks, counts each
///        block's digits (into `counts`, blocks << digit entries), runs the offsets over the
///        digits and, within a digit, over the blocks in order, then scatters each block. A
///        stable scatter like the serial one, so the same order for any number of blocks.
///        `for_blocks(fn)` calls fn(b) for every block b < blocks, on any threads, and returns
///        when all are done.
template <typename B, class ForBlocks>
void radixScatterBlocks(int lo, int passes, int digit, int blocks, std::vector<std::uint64_t>* a,
                        std::vector<std::uint64_t>* a_tmp, std::vector<B>* b, std::vector<B>* b_tmp,
                        std::vector<std::uint32_t>* counts, ForBlocks&& for_blocks) {
  const std::size_t n = a->size();
  if (n == 0) return;
  const std::uint32_t mask = (1u << digit) - 1;
  const std::size_t buckets = std::size_t{1} << digit;
  resizeScratch(a_tmp, n);
  if (b) resizeScratch(b_tmp, n);
  counts->resize(static_cast<std::size_t>(blocks) * buckets);
  std::uint32_t* const cnt = counts->data();
  auto begin = [&](int block) {
    return n * static_cast<std::size_t>(block) / static_cast<std::size_t>(blocks);
  };
  for (int q = 0; q < passes; ++q) {
    const int shift = lo + q * digit;
    const std::uint64_t* const k = a->data();
    std::uint64_t* const kt = a_tmp->data();
    for_blocks([&](int block) {
      std::uint32_t* c = cnt + static_cast<std::size_t>(block) * buckets;
      std::fill(c, c + buckets, 0u);
      const std::size_t e = begin(block + 1);
      for (std::size_t i = begin(block); i < e; ++i) {
        prefetchAhead(k + i, 8 * kRadixReadAhead);
        ++c[(k[i] >> shift) & mask];
      }
    });
    std::size_t first_digit = 0;  // keys with k[0]'s digit
    const std::size_t d0 = (k[0] >> shift) & mask;
    for (int block = 0; block < blocks; ++block) {
      first_digit += cnt[static_cast<std::size_t>(block) * buckets + d0];
    }
    if (first_digit == n) continue;  // every key has this digit
    std::uint32_t sum = 0;
    for (std::size_t j = 0; j < buckets; ++j) {
      for (int block = 0; block < blocks; ++block) {
        std::uint32_t& c = cnt[static_cast<std::size_t>(block) * buckets + j];
        const std::uint32_t here = c;
        c = sum;
        sum += here;
      }
    }
    for_blocks([&](int block) {
      std::uint32_t* c = cnt + static_cast<std::size_t>(block) * buckets;
      const std::size_t e = begin(block + 1);
      if (b) {
        const B* o = b->data();
        B* ot = b_tmp->data();
        for (std::size_t i = begin(block); i < e; ++i) {
          const std::uint32_t dst = c[(k[i] >> shift) & mask]++;
          kt[dst] = k[i];
          ot[dst] = o[i];
        }
        return;
      }
      for (std::size_t i = begin(block); i < e; ++i) {
        prefetchAhead(k + i, 8 * kRadixReadAhead);
        kt[c[(k[i] >> shift) & mask]++] = k[i];
      }
    });
    a->swap(*a_tmp);
    if (b) b->swap(*b_tmp);
  }
}

/// \brief Sorts the keys src[0, len) on the bits [lo, top) into dst[0, len) (src is
///        overwritten): an LSD sort of 8-bit digits, or insertion for a few keys. Stable.
inline void radixSortBucket(int lo, int top, std::uint64_t* src, std::uint64_t* dst,
                            std::size_t len) {
  constexpr int kSub = 8;
  constexpr std::uint32_t kSubMask = (1u << kSub) - 1;
  constexpr std::size_t kInsertion = 24;  // buckets up to this size: insertion sort
  const int m = (top - lo + kSub - 1) / kSub;
  if (len <= kInsertion || m > 8) {
    for (std::size_t i = 0; i < len; ++i) {
      const std::uint64_t w = src[i];
      std::size_t j = i;
      for (; j > 0 && dst[j - 1] > w; --j) dst[j] = dst[j - 1];
      dst[j] = w;
    }
    return;
  }
  std::uint32_t cnt[8][kSubMask + 1];
  for (int q = 0; q < m; ++q) {
    for (std::uint32_t j = 0; j <= kSubMask; ++j) cnt[q][j] = 0;
  }
  if (m == 3) {  // the usual case (24 bits below a 12-bit top digit): unrolled
    for (std::size_t i = 0; i < len; ++i) {
      const std::uint64_t w = src[i] >> lo;
      ++cnt[0][w & kSubMask];
      ++cnt[1][(w >> kSub) & kSubMask];
      ++cnt[2][(w >> (2 * kSub)) & kSubMask];
    }
  } else {
    for (std::size_t i = 0; i < len; ++i) {
      const std::uint64_t w = src[i] >> lo;
      for (int q = 0; q < m; ++q) ++cnt[q][(w >> (q * kSub)) & kSubMask];
    }
  }
  std::uint64_t* const out = dst;
  for (int q = 0; q < m; ++q) {
    std::uint32_t* c = cnt[q];
    const int shift = lo + q * kSub;
    if (c[(src[0] >> shift) & kSubMask] == len) continue;  // one digit for all
    std::uint32_t run = 0;
    for (std::uint32_t j = 0; j <= kSubMask; ++j) {
      const std::uint32_t k = c[j];
      c[j] = run;
      run += k;
    }
    for (std::size_t i = 0; i < len; ++i) dst[c[(src[i] >> shift) & kSubMask]++] = src[i];
    std::swap(src, dst);
  }
  if (src != out) std::copy(src, src + len, out);
}

/// \brief The same order as radixScatter() of the keys alone over `passes` >= 2 digits, for
///        arrays much larger than the cache: one scatter by the top digit (its counts from
///        `hist`), then each bucket (a few thousand keys on large scans, in cache) sorted on the
///        lower bits (radixSortBucket()). With `blocks` > 1 the scatter is radixScatterBlocks()'s
///        (`counts` its buffer) and the buckets go in `blocks` ranges of about n / blocks keys:
///        `for_blocks(fn)` calls fn(b) for every b < blocks, on any threads. Needs keys
///        that are unique and in increasing order of their bits below `lo` (packed
///        key << slot | slot words, written in slot order): then any sort by the bits from
///        `lo` on that keeps equal keys in input order gives the same array. `hist` is
///        overwritten.
/// \returns false, having changed nothing, when a bucket would hold more than `max_bucket`
///          keys (dense scans: TLS near its scanner), which would be sorted out of cache.
template <class ForBlocks>
bool radixSortTopDown(int lo, int passes, int digit, std::uint32_t* hist,
                      std::vector<std::uint64_t>* a, std::vector<std::uint64_t>* a_tmp,
                      std::size_t max_bucket, int blocks, std::vector<std::uint32_t>* counts,
                      ForBlocks&& for_blocks) {
  const std::size_t n = a->size();
  if (n == 0) return true;
  const std::uint32_t mask = (1u << digit) - 1;
  const int top = lo + (passes - 1) * digit;  // shift of the top digit
  std::uint32_t* h = hist + (static_cast<std::size_t>(passes - 1) << digit);
  if (*std::max_element(h, h + mask + 1) > max_bucket) return false;
  std::uint32_t* start = hist;  // pass 0's counts are not needed: bucket starts
  std::uint32_t sum = 0;
  for (std::uint32_t j = 0; j <= mask; ++j) {
    const std::uint32_t cnt = h[j];
    h[j] = start[j] = sum;
    sum += cnt;
  }
  resizeScratch(a_tmp, n);
  if (blocks > 1) {
    radixScatterBlocks<std::uint32_t>(top, 1, digit, blocks, a, a_tmp, nullptr, nullptr, counts,
                                      for_blocks);
    a->swap(*a_tmp);  // the scattered keys in a_tmp, as below
  } else {
    const std::uint64_t* const k = a->data();
    std::uint64_t* const kt = a_tmp->data();
    for (std::size_t i = 0; i < n; ++i) kt[h[(k[i] >> top) & mask]++] = k[i];
  }
  std::uint64_t* const ka = a->data();
  std::uint64_t* const kb = a_tmp->data();
  // The buckets on the bits [lo, top) into `ka`, in ranges starting at the first bucket that
  // starts at or after n * b / blocks.
  auto first_bucket = [&](int b) {
    const std::uint32_t at = static_cast<std::uint32_t>(n * static_cast<std::size_t>(b) /
                                                        static_cast<std::size_t>(blocks));
    return static_cast<std::uint32_t>(std::lower_bound(start, start + mask + 1, at) - start);
  };
  for_blocks([&](int b) {
    const std::uint32_t b1 = b + 1 < blocks ? first_bucket(b + 1) : mask + 1;
    for (std::uint32_t j = first_bucket(b); j < b1; ++j) {
      const std::size_t end = j < mask ? start[j + 1] : n;
      radixSortBucket(lo, top, kb + start[j], ka + start[j], end - start[j]);
    }
  });
  return true;
}

/// \brief radixSortTopDown() on the calling thread.
inline bool radixSortTopDown(int lo, int passes, int digit, std::uint32_t* hist,
                             std::vector<std::uint64_t>* a, std::vector<std::uint64_t>* a_tmp,
                             std::size_t max_bucket) {
  return radixSortTopDown(lo, passes, digit, hist, a, a_tmp, max_bucket, 1, nullptr,
                          [](const auto& fn) { fn(0); });
}

/// \brief Buffers of radixSortByKey(), reused between calls.
struct RadixSortScratch {
  std::vector<std::uint64_t> keys, keys_tmp;
  std::vector<std::uint32_t> order_tmp, hist;
};

/// Inputs smaller than this many keys per thread sort on one thread.
constexpr std::size_t kRadixPointsPerThread = 32768;

/// Inputs up to this many keys sort on one thread as packed key << index | index words
/// (radixSortPacked()) where key and index fit in 64 bits: a pass moves 8 bytes a key instead
/// of 12, and at these sizes that beats two threads (a KITTI frame's column sort about 0.4 ms
/// shorter, docs/normal_speed.md).
constexpr std::size_t kRadixPackedMaxPoints = std::size_t{1} << 20;

/// \brief radixSortByKey() of n >= 2 keys as packed words key << index_bits | index on the
///        calling thread, `passes` digits of `digit` bits (keys and index fit in 64 bits): equal
///        keys keep index order, so the same order. `order` holds n entries.
inline void radixSortPacked(const std::vector<std::uint64_t>& keys, int passes, int digit,
                            std::vector<std::uint32_t>* order, RadixSortScratch* s) {
  const std::size_t n = keys.size();
  const int index_bits = radixBitsFor(n - 1);
  const std::uint32_t mask = (1u << digit) - 1;
  std::vector<std::uint64_t>& words = s->keys;
  words.resize(n);
  s->hist.assign(static_cast<std::size_t>(passes) << digit, 0);
  std::uint32_t* hist = s->hist.data();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t k = keys[i];
    words[i] = k << index_bits | i;
    for (int q = 0; q < passes; ++q) {
      ++hist[(static_cast<std::size_t>(q) << digit) + ((k >> (q * digit)) & mask)];
    }
  }
  radixScatter<std::uint32_t>(index_bits, passes, digit, hist, &words, &s->keys_tmp, nullptr,
                              nullptr);
  const std::uint64_t index_mask = (std::uint64_t{1} << index_bits) - 1;
  for (std::size_t j = 0; j < n; ++j) {  // the order, and the keys where the words were
    (*order)[j] = static_cast<std::uint32_t>(words[j] & index_mask);
    words[j] >>= index_bits;
  }
}

/// \brief radixSortPacked() on `threads` > 1 threads (OpenMP): the words written in blocks, then
///        radixScatterBlocks() over the digits, one block a thread, and the order and keys taken
///        back in blocks; the same order as on one thread. On a KITTI frame's column sort the
///        serial passes left the filter's second thread waiting (docs/normal_speed.md).
inline void radixSortPackedParallel(const std::vector<std::uint64_t>& keys, int passes, int digit,
                                    int threads, std::vector<std::uint32_t>* order,
                                    RadixSortScratch* s) {
  const std::int64_t n = static_cast<std::int64_t>(keys.size());
  const int index_bits = radixBitsFor(static_cast<std::uint64_t>(n - 1));
  std::vector<std::uint64_t>& words = s->keys;
  words.resize(keys.size());
  const std::uint64_t* const k = keys.data();
  std::uint64_t* const w = words.data();
#pragma omp parallel for num_threads(threads) schedule(static)
  for (std::int64_t i = 0; i < n; ++i) w[i] = k[i] << index_bits | static_cast<std::uint64_t>(i);
  radixScatterBlocks<std::uint32_t>(index_bits, passes, digit, threads, &words, &s->keys_tmp,
                                    nullptr, nullptr, &s->hist, [threads](const auto& fn) {
#pragma omp parallel for num_threads(threads) schedule(static, 1)
                                      for (int t = 0; t < threads; ++t) fn(t);
                                    });
  const std::uint64_t index_mask = (std::uint64_t{1} << index_bits) - 1;
  std::uint64_t* const sorted = words.data();
  std::uint32_t* const o = order->data();
#pragma omp parallel for num_threads(threads) schedule(static)
  for (std::int64_t j = 0; j < n; ++j) {  // the order, and the keys where the words were
    o[j] = static_cast<std::uint32_t>(sorted[j] & index_mask);
    sorted[j] >>= index_bits;
  }
}

/// \brief radixSortByKey() with `threads` > 1: radixScatterBlocks() over the digits, one block a
///        thread (OpenMP), keys and order together; the same order for any thread count.
inline void radixSortByKeyParallel(int passes, int digit, int threads,
                                   std::vector<std::uint32_t>* order, RadixSortScratch* s) {
  radixScatterBlocks(0, passes, digit, threads, &s->keys, &s->keys_tmp, order, &s->order_tmp,
                     &s->hist, [threads](const auto& fn) {
#pragma omp parallel for num_threads(threads) schedule(static, 1)
                       for (int t = 0; t < threads; ++t) fn(t);
                     });
}

/// \brief `order` = 0 .. n-1 sorted by `keys` (stable: equal keys keep index order), through
///        radixScatter() on a copy of the keys; digits as wide as the largest key needs. With
///        `threads` > 1 large inputs sort on several threads (radixSortByKeyParallel(), the same
///        order). Afterwards `s->keys` holds the keys in sorted order.
inline void radixSortByKey(const std::vector<std::uint64_t>& keys,
                           std::vector<std::uint32_t>* order, RadixSortScratch* s,
                           int threads = 1) {
  const std::size_t n = keys.size();
  order->resize(n);
  if (n < 2) {
    if (n == 1) (*order)[0] = 0;
    s->keys = keys;
    return;
  }
  std::uint64_t any = 0;
  for (const std::uint64_t k : keys) any |= k;
  const int bits = radixBitsFor(any);
  const int passes = (bits + kRadixMaxDigitBits - 1) / kRadixMaxDigitBits;
  const int digit = (bits + passes - 1) / passes;
  const int nt =
      static_cast<int>(std::min<std::size_t>(threads > 1 ? threads : 1, n / kRadixPointsPerThread));
  if (n <= kRadixPackedMaxPoints && bits + radixBitsFor(n - 1) <= 64) {
    if (nt > 1) {
      radixSortPackedParallel(keys, passes, digit, nt, order, s);
    } else {
      radixSortPacked(keys, passes, digit, order, s);
    }
    return;
  }
  for (std::size_t i = 0; i < n; ++i) (*order)[i] = static_cast<std::uint32_t>(i);
  const std::uint32_t mask = (1u << digit) - 1;
  if (nt > 1) {
    s->keys = keys;
    radixSortByKeyParallel(passes, digit, nt, order, s);
    return;
  }
  s->hist.assign(static_cast<std::size_t>(passes) << digit, 0);
  std::uint32_t* hist = s->hist.data();
  for (const std::uint64_t k : keys) {
    for (int q = 0; q < passes; ++q) {
      ++hist[(static_cast<std::size_t>(q) << digit) + ((k >> (q * digit)) & mask)];
    }
  }
  s->keys = keys;
  radixScatter(0, passes, digit, hist, &s->keys, &s->keys_tmp, order, &s->order_tmp);
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_RADIX_SORT_H
