// Private to the voxel filter: AVX2 versions of passes of the Voxelizer over the points (bounds,
// voxel keys) and the voxels (centroids, flags), eight a step. Compiled with a function target
// attribute and chosen at run time (Voxelizer::setUseAvx2()), so the package still runs on any
// x86-64; the arithmetic is the SSE2 code's lane by lane (same keys, same bounds).
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_AVX2_PASSES_H
#define GROUND_FILTER_SRC_CORE_VOXEL_AVX2_PASSES_H

#include <cstddef>
#include <cstdint>

#include "voxel/voxel_grid.h"

namespace ground_filter {
namespace voxel {

/// \brief What the key pass needs, by value (no aliasing with the arrays it writes).
struct KeyJob {
  std::uint64_t* keys;   // key, or key << slot_bits | slot when packed
  std::uint32_t* order;  // slot per key (not packed)
  std::uint32_t* index;  // input index per slot (not all valid)
  std::uint32_t* hist;   // digit counts of every radix pass
  float min[4];
  float inv_vs;
  std::int32_t last[4];  // voxels per axis - 1
  int shift_x, shift_y;
  int passes, digit, shift_lo, slot_bits;
  bool packed, all_valid;
};

/// \brief Records with x y z adjacent: the passes read them with one 16-byte load a record.
struct DirectRead {
  const std::uint8_t* x = nullptr;  // x of record 0 (null: another layout)
  std::size_t step = 0;             // bytes from one record to the next
  std::size_t vector_end = 0;       // records before this one have 16 bytes from x on
};

/// \brief A ground seed needs this many empty voxels above it in its column: the foot of a wall,
///        a car side or a fence has occupied voxels right above it, the ground does not.
constexpr std::uint32_t kSeedClearanceVoxels = 3;

/// \brief What the voxel flags and lists are made of (sorted voxels of a VoxelGrid being built).
struct VoxelFlagsJob {
  const std::uint64_t* vkey;    // key per voxel
  const std::uint32_t* vstart;  // first point per voxel, nv + 1 entries
  const float* rec;             // record per voxel; its float 3 is max z - min z
  std::size_t rec_floats;       // floats a record
  std::size_t nv;               // voxels
  int shift_y;                  // key >> shift_y: column
  std::uint64_t mask_z;         // key & mask_z: z
  std::uint32_t min_pts;        // min_points_per_voxel
  float flat_thr;               // flatness_threshold
  bool local;                   // local_planes: the flat list holds the flat seed candidates only
};

/// \brief The voxel lists (buffers of nv entries, col_first nv + 1) and their lengths so far.
struct VoxelLists {
  std::uint32_t* col_first;  // first voxel of each column
  std::uint32_t* flat;       // region growing input (see voxelFlags())
  std::uint32_t* seeds;      // seed candidates of the local model
  std::size_t ncol, nflat, nseed;
};

/// \brief Flags (kFlat | kSeed) of voxels [begin, end) into `flags`, appended to the lists.
inline void voxelFlags(const VoxelFlagsJob& j, std::size_t begin, std::size_t end,
                       std::uint8_t* flags, VoxelLists* out) {
  for (std::size_t v = begin; v < end; ++v) {
    const std::uint64_t key = j.vkey[v];
    const std::uint64_t col = key >> j.shift_y;
    const std::uint32_t cnt = j.vstart[v + 1] - j.vstart[v];
    // ---- flat voxels (paper): enough points and a small height range.
    const bool is_flat = (cnt >= j.min_pts) & (j.rec[j.rec_floats * v + 3] < j.flat_thr);
    // ---- seed candidates of the local model: the lowest voxel of its column with free space
    // above it, flat or too sparse to tell (far, sparse ground).
    const bool lowest = v == 0 || (j.vkey[v - 1] >> j.shift_y) != col;
    const std::uint64_t next = v + 1 < j.nv ? j.vkey[v + 1] : ~std::uint64_t{0};
    const bool clear = ((next >> j.shift_y) != col) |
                       ((next & j.mask_z) - (key & j.mask_z) > kSeedClearanceVoxels);
    const bool is_seed = (is_flat | (cnt < j.min_pts)) & lowest & clear;
    flags[v] = static_cast<std::uint8_t>((is_flat ? kFlat : 0) | (is_seed ? kSeed : 0));
    // Lists without a branch: a store is always made, the length moves when v belongs. Region
    // growing input: every flat voxel (paper) for the global plane; for the local model only
    // the flat seed candidates (the same components on the ground, 3x less work, and wall
    // voxels stacked line over line drop out).
    const std::uint32_t vv = static_cast<std::uint32_t>(v);
    out->col_first[out->ncol] = vv;
    out->ncol += lowest;
    out->flat[out->nflat] = vv;
    out->nflat += is_flat & (is_seed | !j.local);
    out->seeds[out->nseed] = vv;
    out->nseed += is_seed;
  }
}

/// \brief Whether this build has the AVX2 passes and this CPU runs them.
bool cpuHasAvx2();

/// \brief Packed keys (job.packed, every point valid) and their digit counts of records [begin,
///        end) of `rows`, written from slot `slot` on, in blocks of eight (records before
///        rows.vector_end only). Returns the first record not done (the rest is the caller's).
std::size_t computeKeysAvx2(const KeyJob& job, const DirectRead& rows, std::size_t begin,
                            std::size_t end, std::size_t slot);

/// \brief Bounds of the records of [begin, end) of `rows` with finite x y z (lo, hi: x y z and a
///        lane not used; updated, not reset) and their number (added to *valid), in blocks of
///        eight (records before rows.vector_end only). Returns the first record not done.
std::size_t scanBoundsAvx2(const DirectRead& rows, std::size_t begin, std::size_t end, float lo[4],
                           float hi[4], std::size_t* valid);

/// \brief Centroids of voxels [0, nv) from their sums (`rec`: x y z sums and one float not used
///        per voxel) and first points (`vstart`, nv + 1 entries), in blocks of eight. Returns
///        the first voxel not done.
std::size_t centroidsAvx2(const float* rec, const std::uint32_t* vstart, std::size_t nv, float* vx,
                          float* vy, float* vz);

/// \brief voxelFlags() from voxel 0 on, blocks of eight inside. Returns the first voxel not
///        done.
std::size_t voxelFlagsAvx2(const VoxelFlagsJob& j, std::uint8_t* flags, VoxelLists* out);

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_AVX2_PASSES_H
