// Private to the voxel filter: valid points, voxel keys, radix sort, voxels, columns, flags.
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_VOXELIZE_H
#define GROUND_FILTER_SRC_CORE_VOXEL_VOXELIZE_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/voxel_ground_filter_params.h"
#include "ground_filter/working_volume_params.h"
#include "simd/simd.h"
#include "voxel/avx2_passes.h"
#include "voxel/voxel_grid.h"
#include "voxel/worker_pool.h"

namespace ground_filter {
namespace voxel {

/// \brief Steps 1-2 and the seed candidates of step 6: sorts the valid points by voxel key and
///        builds the voxels, their flags, cells and the columns of a VoxelGrid.
class Voxelizer {
 public:
  /// \brief x y z adjacent in every record: the passes can read them with one 16-byte load a
  ///        point (the AVX2 passes take the same description).
  using DirectRead = voxel::DirectRead;
  /// \brief prepare()'s answer when a valid point may lie outside the volume.
  static constexpr std::size_t kOutside = ~std::size_t{0};
  /// \brief Finds the valid points and their bounds, sizes the key layout of `g` and computes
  ///        the keys. Returns the number of valid points (0: `g` is left as is), or kOutside
  ///        (nothing else done) when `volume` is given and the bounds are not inside it.
  /// \throws std::runtime_error when an axis needs more than 2^21 voxels.
  std::size_t prepare(const CloudView& cloud, double voxel_size, int threads, WorkerPool* pool,
                      const WorkingVolume* volume, VoxelGrid* g);
  /// \brief Sorts the keys and fills the points, voxels, columns, `flat` and `seeds` of `g`;
  ///        marks the cells holding voxels in `cells`.
  ///        From setParallelMinPoints() valid points on, the sort, the gather of the points,
  ///        the centroids and the cells run on `threads` threads of `pool` (the same grid for
  ///        any thread count).
  void build(const VoxelGroundFilterParams& p, int threads, WorkerPool* pool, VoxelGrid* g,
             CellGrid* cells);
  /// \brief Valid points from which build() uses several threads (default
  ///        kParallelSortMinPoints; tests lower it).
  void setParallelMinPoints(std::size_t n) { parallel_min_points_ = n; }
  /// \brief Whether prepare() and build() may run their AVX2 passes (default: yes, where the
  ///        SIMD level in force, simd::active(), includes AVX2); tests compare both paths.
  void setUseAvx2(bool use) { use_avx2_ = use; }
  /// \brief Whether the passes over points use vectors of 4 floats, SSE2 (SIMD level sse and up
  ///        on x86-64) or NEON (level neon on aarch64), or plain floats (level portable): the
  ///        same keys, bounds and sums.
  static bool useVector();

 private:
  // Whether the AVX2 passes run: allowed here and by the SIMD level in force.
  bool useAvx2() const { return use_avx2_ && simd::allows(simd::Level::kAvx2) && cpuHasAvx2(); }
  struct RadixPlan {
    int lo = 0, passes = 0, digit = 1;
    std::uint32_t mask() const { return (1u << digit) - 1; }
  };
  struct Chunk {                                         // one thread's share of the input
    std::size_t begin = 0, end = 0, valid = 0, out = 0;  // input range, valid points, first slot
    float lo[3], hi[3];                                  // bounds of its valid points
  };
  template <class O>  // O: the V4 operations (voxelize.cpp)
  static void scanBounds(const CloudView& cloud, const DirectRead& direct, float* pts, bool avx2,
                         Chunk* ch);
  // prepare(), after the bounds: sizes the key layout of `g` (throws when an axis is too long);
  // returns the key bits.
  int layoutKeys(const float lo[3], const float hi[3], double vs, std::size_t n, VoxelGrid* g);
  // prepare()'s second pass: the keys of the `n` valid points and the radix digit counts.
  void keyPass(double vs, int key_bits, std::size_t n, int nt, int nch, WorkerPool* pool,
               VoxelGrid* g);
  void sort(int threads, WorkerPool* pool, VoxelGrid* g);
  // build() pass 1: points in key order, voxels and their sums; returns the number of voxels.
  std::size_t gatherPoints(int nt, WorkerPool* pool, VoxelGrid* g);
  // build() pass 2, per voxel: centroids, flags, cells, columns, the flat and seed lists.
  void voxelPasses(const VoxelGroundFilterParams& p, int nt, std::size_t nv, WorkerPool* pool,
                   VoxelGrid* g, CellGrid* cells);

  // x y z 0 per input point (16-byte aligned vectors), absolute: build() subtracts min_ as it
  // gathers the valid points (one write of the copy fewer than storing relative coordinates).
  // Made only for records of more than 16 bytes or with x y z apart (copied()); records of
  // 12-16 bytes with x y z adjacent (packed x y z, KITTI's x y z intensity) are read in place
  // (a wide record read twice at random in the gather cost more than the copy: os128).
  std::vector<float> pxyz_;
  bool use_avx2_ = true;
  bool vec_ = false, avx2_ = false;  // this scan's passes (prepare(); build() keeps them)
  std::size_t parallel_min_points_ = kParallelSortMinPoints;
  std::vector<std::uint32_t> block_counts_;      // sort() on several threads: digits per block
  std::vector<std::size_t> range_, voxel_base_;  // build(): points and first voxel per range
  DirectRead direct_;  // this scan's layout (prepare(); build() reads the same cloud)
  bool copied() const { return direct_.x == nullptr || direct_.step > 16; }
  float min_[3] = {0.f, 0.f, 0.f};  // min corner of the valid points
  std::vector<Chunk> chunks_;
  Buffer<float> vrec_;  // build(): sums and z range per voxel (gatherRuns())
  std::vector<std::uint64_t> keys_tmp_;
  std::vector<std::uint32_t> order_tmp_;
  RadixPlan plan_;
  // Digit counts of every radix pass (counted by prepare(), one histogram per thread, summed
  // into the first).
  std::vector<std::uint32_t> hist_;
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_VOXELIZE_H
