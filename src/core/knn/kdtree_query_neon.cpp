// KdTreeNeighborSearch: the NEON top-K set of aarch64 (2 keys per register, candidates packed by a
// byte table).

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>

#include "knn/kdtree_tree.h"
#include "simd/neon_common.h"
#include "simd/simd.h"

namespace ground_filter {
namespace kdtree {

#if GF_HAVE_NEON_PATHS

// The scheme of TopKAvx2 with 128-bit registers: distances 4 at a time, candidates within the
// bound packed into a buffer (no branch per candidate), full buffers sorted by a bitonic network
// over 2 keys per register and merged into the sorted top K. NEON compares 64-bit lanes
// unsigned, so an empty slot is kNoKey itself.

namespace {  // the set and its helpers; only the entry point below is shared

inline void compareExchange2(uint64x2_t* a, uint64x2_t* b) {
  const uint64x2_t gt = vcgtq_u64(*a, *b);
  const uint64x2_t lo = vbslq_u64(gt, *b, *a);
  *b = vbslq_u64(gt, *a, *b);
  *a = lo;
}

inline uint64x2_t reverseLanes2(uint64x2_t v) { return vextq_u64(v, v, 1); }

/// Sorts a register's 2 lanes.
inline uint64x2_t laneMerge2(uint64x2_t v) {
  const uint64x2_t p = reverseLanes2(v);
  const uint64x2_t gt = vcgtq_u64(v, p);
  // Lane 0 of the minima and lane 0 of the maxima (both lanes of each hold the same value).
  return vzip1q_u64(vbslq_u64(gt, p, v), vbslq_u64(gt, v, p));
}

/// Register-level half-cleaners over v[0..R) at distances s_max, ..., 1, then each register's
/// lanes.
template <int R>
inline void halfCleanAndMerge2(uint64x2_t* v, int s_max) {
  for (int s = s_max; s >= 1; s /= 2) {
    for (int i = 0; i < R; ++i) {
      if (i & s) continue;
      compareExchange2(&v[i], &v[i + s]);
    }
  }
  for (int i = 0; i < R; ++i) v[i] = laneMerge2(v[i]);
}

/// Sorts each of 2 registers: one compare-exchange across them, then a 2 x 2 transpose.
inline void sortRegisters2(uint64x2_t* v) {
  compareExchange2(&v[0], &v[1]);
  const uint64x2_t t0 = vzip1q_u64(v[0], v[1]), t1 = vzip2q_u64(v[0], v[1]);
  v[0] = t0;
  v[1] = t1;
}

/// Sorts the 2R keys of v ascending (R a power of two, at least 2).
template <int R>
inline void bitonicSort2(uint64x2_t* v) {
  for (int i = 0; i < R; i += 2) sortRegisters2(v + i);
  for (int size = 2; size <= R; size *= 2) {  // merge sorted runs of size / 2 registers
    for (int blk = 0; blk < R; blk += size) {
      for (int j = 0; j < size / 2; ++j) {
        uint64x2_t a = v[blk + j], b = reverseLanes2(v[blk + size - 1 - j]);
        compareExchange2(&a, &b);
        v[blk + j] = a;
        v[blk + size - 1 - j] = reverseLanes2(b);
      }
    }
    halfCleanAndMerge2<R>(v, size / 4);
  }
}

/// For each 4-bit mask, the bytes that move its set 32-bit lanes to the front.
struct CompressTableNeon {
  std::uint8_t bytes[16][16];
  constexpr CompressTableNeon() : bytes() {
    for (int m = 0; m < 16; ++m) {
      int o = 0;
      for (int lane = 0; lane < 4; ++lane) {
        if (!(m & (1 << lane))) continue;
        for (int b = 0; b < 4; ++b) bytes[m][4 * o + b] = static_cast<std::uint8_t>(4 * lane + b);
        ++o;
      }
      for (; o < 4; ++o) {
        for (int b = 0; b < 4; ++b) bytes[m][4 * o + b] = 0;
      }
    }
  }
};
constexpr CompressTableNeon kCompressNeon{};

/// The best K <= 2R keys, sorted, fed by a buffer of candidates within the threshold.
template <int R>
class TopKNeon {
 public:
  static constexpr int kSlots = 2 * R;

  void init(int k, float bound) {
    k_ = k;
    pending_ = 0;
    thr_ = bound;
    empty_ = true;
  }
  float threshold() const { return thr_; }

  static float boxDist(const Node& nd, const float* q) {
    const float32x4_t q4 = vld1q_f32(q);  // q[3] = 0, like the boxes' padding
    const float32x4_t lo = vld1q_f32(nd.lo), hi = vld1q_f32(nd.hi);
    const float32x4_t t =
        vmaxq_f32(vmaxq_f32(vsubq_f32(lo, q4), vsubq_f32(q4, hi)), vdupq_n_f32(0.f));
    const float32x4_t t2 = simd::neon::opaque(vmulq_f32(t, t));
    return (vgetq_lane_f32(t2, 0) + vgetq_lane_f32(t2, 1)) + vgetq_lane_f32(t2, 2);
  }

  void scan(const Tree& t, const Node& nd, const float* q) {
    using simd::neon::opaque;
    const std::uint32_t b = nd.begin;
    int m = static_cast<int>(nd.scan_end - b);
    const float *x = t.px.data() + b, *y = t.py.data() + b, *z = t.pz.data() + b;
    const std::uint32_t* ids = t.pidx.data() + b;
    if (nd.right == kSamePoint && !empty_) {
      const float dx = q[0] - x[0], dy = q[1] - y[0], dz = q[2] - z[0];
      const float32x4_t v = {dx, dy, dz, 0.f};
      const float32x4_t d2 = opaque(vmulq_f32(v, v));
      const float d = (vgetq_lane_f32(d2, 0) + vgetq_lane_f32(d2, 1)) + vgetq_lane_f32(d2, 2);
      m = samePointPrefix(ids, m, d, top_[k_ - 1]);
    }
    const float32x4_t qx = vdupq_n_f32(q[0]), qy = vdupq_n_f32(q[1]), qz = vdupq_n_f32(q[2]);
    const uint32x4_t lane_bit = {1, 2, 4, 8};
    const uint32x4_t lane = {0, 1, 2, 3};
    int pending = pending_;  // in registers: see TopKAvx512::scan()
    float32x4_t thr = vdupq_n_f32(thr_);
    for (int j = 0; j < m; j += 4) {
      float32x4_t px, py, pz;
      uint32x4_t pi;
      uint32x4_t valid = vdupq_n_u32(~0u);
      if (m - j >= 4) {
        px = vld1q_f32(x + j);
        py = vld1q_f32(y + j);
        pz = vld1q_f32(z + j);
        pi = vld1q_u32(ids + j);
      } else {  // the leaf's last block: lane by lane (no read past the arrays)
        float bx[4] = {0.f, 0.f, 0.f, 0.f}, by[4] = {0.f, 0.f, 0.f, 0.f},
              bz[4] = {0.f, 0.f, 0.f, 0.f};
        std::uint32_t bi[4] = {0, 0, 0, 0};
        for (int l = 0; l < m - j; ++l) {
          bx[l] = x[j + l];
          by[l] = y[j + l];
          bz[l] = z[j + l];
          bi[l] = ids[j + l];
        }
        px = vld1q_f32(bx);
        py = vld1q_f32(by);
        pz = vld1q_f32(bz);
        pi = vld1q_u32(bi);
        valid = vcltq_u32(lane, vdupq_n_u32(static_cast<std::uint32_t>(m - j)));
      }
      const float32x4_t dx = vsubq_f32(qx, px), dy = vsubq_f32(qy, py), dz = vsubq_f32(qz, pz);
      const float32x4_t d =
          vaddq_f32(vaddq_f32(opaque(vmulq_f32(dx, dx)), opaque(vmulq_f32(dy, dy))),
                    opaque(vmulq_f32(dz, dz)));
      const uint32x4_t in = vandq_u32(vcleq_f32(d, thr), valid);
      const unsigned keep = vaddvq_u32(vandq_u32(in, lane_bit));
      // No branch on `keep`: pack through the byte table, always store 4 lanes.
      const uint8x16_t perm = vld1q_u8(kCompressNeon.bytes[keep]);
      vst1q_u32(cand_d_ + pending, vreinterpretq_u32_u8(vqtbl1q_u8(vreinterpretq_u8_f32(d), perm)));
      vst1q_u32(cand_i_ + pending,
                vreinterpretq_u32_u8(vqtbl1q_u8(vreinterpretq_u8_u32(pi), perm)));
      pending += __builtin_popcount(keep);
      if (pending >= kSlots) {
        const int extra = pending - kSlots;
        pending_ = kSlots;
        flush();
        // Move the candidates past the flushed block to the front (extra < 4).
        vst1q_u32(cand_d_, vld1q_u32(cand_d_ + kSlots));
        vst1q_u32(cand_i_, vld1q_u32(cand_i_ + kSlots));
        pending = extra;
        thr = vdupq_n_f32(thr_);
      }
    }
    pending_ = pending;
  }

  void finish() {
    if (pending_ > 0 || empty_) flush();
  }
  bool complete() const { return top_[k_ - 1] != kNoKey; }
  std::uint64_t key(int j) const { return top_[j]; }

  void write(std::int32_t* idx, float* dist) const {
    int j = 0;
    for (; j + 2 <= k_; j += 2) {
      const uint64x2_t keys = vld1q_u64(top_ + j);
      vst1_s32(idx + j, vreinterpret_s32_u32(vmovn_u64(keys)));  // low halves: indices
      if (dist) vst1_f32(dist + j, vreinterpret_f32_u32(vshrn_n_u64(keys, 32)));
    }
    for (; j < k_; ++j) {
      idx[j] = static_cast<std::int32_t>(static_cast<std::uint32_t>(top_[j]));
      if (dist) dist[j] = keyDist(top_[j]);
    }
  }

 private:
  /// Sorts the pending candidates and merges them into the top list.
  void flush() {
    uint64x2_t c[R];
    const uint64x2_t none = vdupq_n_u64(kNoKey);
    const uint64x2_t count = vdupq_n_u64(static_cast<std::uint64_t>(pending_));
    const int used = (pending_ + 1) / 2;
    for (int r = 0; r < R; ++r) {
      if (r >= used) {
        c[r] = none;
        continue;
      }
      const uint32x2_t d = vld1_u32(cand_d_ + 2 * r);
      const uint32x2_t i = vld1_u32(cand_i_ + 2 * r);
      const uint64x2_t key = vorrq_u64(vshll_n_u32(d, 32), vmovl_u32(i));
      const uint64x2_t lane = {static_cast<std::uint64_t>(2 * r),
                               static_cast<std::uint64_t>(2 * r + 1)};
      c[r] = vbslq_u64(vcgtq_u64(count, lane), key, none);
    }
    // Registers past the candidates hold only empty slots: sort just the used ones.
    if (used <= 4) {
      bitonicSort2<4>(c);
    } else if (R >= 8 && used <= 8) {
      bitonicSort2<(R >= 8 ? 8 : 4)>(c);
    } else if (R >= 16 && used <= 16) {
      bitonicSort2<(R >= 16 ? 16 : 4)>(c);
    } else if (R >= 32 && used <= 32) {
      bitonicSort2<(R >= 32 ? 32 : 4)>(c);
    } else if (R >= 64 && used <= 64) {
      bitonicSort2<(R >= 64 ? 64 : 4)>(c);
    } else {
      bitonicSort2<R>(c);
    }
    if (empty_) {
      for (int r = 0; r < R; ++r) vst1q_u64(top_ + 2 * r, c[r]);
      empty_ = false;
    } else {
      // Smallest 2R of two sorted lists: min(top[i], c[2R-1-i]) is bitonic; merge it.
      uint64x2_t t[R];
      for (int r = 0; r < R; ++r) {
        uint64x2_t a = vld1q_u64(top_ + 2 * r);
        uint64x2_t b = reverseLanes2(c[R - 1 - r]);
        compareExchange2(&a, &b);
        t[r] = a;
      }
      halfCleanAndMerge2<R>(t, R / 2);
      for (int r = 0; r < R; ++r) vst1q_u64(top_ + 2 * r, t[r]);
    }
    pending_ = 0;
    const std::uint64_t kth = top_[k_ - 1];
    if (kth != kNoKey) thr_ = std::min(thr_, keyDist(kth));
  }

  alignas(16) std::uint64_t top_[kSlots];
  alignas(16) std::uint32_t cand_d_[kSlots + 4];  // squared distance bits
  alignas(16) std::uint32_t cand_i_[kSlots + 4];  // point indices
  int k_ = 0, pending_ = 0;
  float thr_ = 0.f;
  bool empty_ = true;
};

}  // namespace

void queryRangeNeon(const Tree& t, std::size_t pb, std::size_t pe, int k, std::int32_t* out_idx,
                    float* out_dist) {
  if (k <= 16) {
    TopKNeon<8> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 32) {
    TopKNeon<16> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 64) {
    TopKNeon<32> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else if (k <= 128) {
    TopKNeon<64> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  } else {
    TopKNeon<128> set;
    queryRange(t, pb, pe, k, &set, out_idx, out_dist);
  }
}

#endif  // GF_HAVE_NEON_PATHS

}  // namespace kdtree
}  // namespace ground_filter
