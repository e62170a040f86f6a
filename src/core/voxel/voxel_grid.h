// Private to the voxel filter: the data every stage of src/core/voxel/ reads (points sorted by
// voxel key, voxels, columns, ground-model cells) and the small math shared by the stages.
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_VOXEL_GRID_H
#define GROUND_FILTER_SRC_CORE_VOXEL_VOXEL_GRID_H

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "ground_filter/voxel_ground_filter_params.h"

namespace ground_filter {
namespace voxel {

constexpr int kMaxAxisBits = 21;  // 3 * 21 bits fit one 64-bit key

// Stages split their work over `threads` only from this many valid points: below it the
// parallel regions cost more than they save (a KITTI frame, 124 k points, stays on one thread).
constexpr std::size_t kParallelMinPoints = 150000;
// The voxel sort and the gather of the points use several threads from this many valid points:
// on a 240 k-point scan two threads sorting share the cache lines of their buckets (a few keys
// each; voxelize 2.6 -> 3.2 ms) and gathering saved nothing; on 1.1 M points both save 15 %
// (docs/voxel_method.md, "Results").
constexpr std::size_t kParallelSortMinPoints = 1000000;
// Sorts of at least this many packed keys with 3 or more radix digits scatter once by the top
// digit and finish each bucket in cache (radixSortTopDown()).
constexpr std::size_t kTopDownSortMinPoints = 1000000;
// ... unless a bucket of the top digit would hold more keys than this (512 KB, in L2; a TLS
// scan, dense near its scanner, has buckets of 230 k keys and sorts faster with LSD passes).
constexpr std::size_t kTopDownSortMaxBucket = 65536;

// Voxel flags.
constexpr std::uint8_t kFlat = 1;  // enough points and a small height range (paper)
constexpr std::uint8_t kSeed = 2;  // ground seed candidate of the local model

// "No voxel" ends of a z range.
constexpr std::int32_t kNoLo = std::numeric_limits<std::int32_t>::max() / 2;
constexpr std::int32_t kNoHi = -kNoLo;

/// \brief Allocator whose resize() leaves new elements of trivial types uninitialised: buffers
///        that are written through pointers and cut to length need no zeroing when they grow.
template <typename T>
struct UninitAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = UninitAllocator<U>;
  };
  UninitAllocator() = default;
  template <typename U>
  UninitAllocator(const UninitAllocator<U>&) noexcept {}
  template <typename U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
/// \brief A vector that does not zero what it grows by.
template <typename T>
using Buffer = std::vector<T, UninitAllocator<T>>;

/// \brief An array whose growth leaves the new memory untouched: not zeroed, nor copied. A large
///        one comes from fresh pages, which take no RAM until written. For the per-cell data of
///        the ground model, whose grid spans a scan's whole x/y extent (up to 4 Mi cells) while
///        a scan writes, before it reads, only the cells near its points: a few clusters 1.4 km
///        apart then keep RAM for those cells only (docs/ros_integration.md). Not Buffer: its
///        growth copies the old elements, and its construct() still runs the default member
///        initialisers of Moments and HeightPlane, which writes every new cell.
template <typename T>
class UntouchedArray {
  static_assert(std::is_trivially_copyable<T>::value, "raw memory holds only plain values");

 public:
  /// \brief n elements; when that needs more room, the old contents are dropped.
  void resize(std::size_t n) {
    if (n > capacity_) {
      data_.reset(static_cast<T*>(std::malloc(std::max<std::size_t>(n, 1) * sizeof(T))));
      if (!data_) {
        capacity_ = size_ = 0;
        throw std::bad_alloc();
      }
      capacity_ = n;
    }
    size_ = n;
  }
  /// \brief n elements, each `value` (all written).
  void assign(std::size_t n, const T& value) {
    resize(n);
    std::fill(data(), data() + n, value);
  }
  T& operator[](std::size_t i) { return data_.get()[i]; }
  const T& operator[](std::size_t i) const { return data_.get()[i]; }
  T* data() { return data_.get(); }
  const T* data() const { return data_.get(); }
  std::size_t size() const { return size_; }

 private:
  struct Free {
    void operator()(T* p) const { std::free(p); }
  };
  std::unique_ptr<T, Free> data_;
  std::size_t size_ = 0, capacity_ = 0;
};

/// \brief Weighted first and second moments of (x, y, z) for height-field plane fits.
struct Moments {
  double w = 0, x = 0, y = 0, z = 0, xx = 0, xy = 0, yy = 0, xz = 0, yz = 0;
  void add(double px, double py, double pz, double pw) {
    w += pw;
    x += pw * px;
    y += pw * py;
    z += pw * pz;
    xx += pw * px * px;
    xy += pw * px * py;
    yy += pw * py * py;
    xz += pw * px * pz;
    yz += pw * py * pz;
  }
  void add(const Moments& o) {
    w += o.w;
    x += o.x;
    y += o.y;
    z += o.z;
    xx += o.xx;
    xy += o.xy;
    yy += o.yy;
    xz += o.xz;
    yz += o.yz;
  }
};

/// \brief Ground surface z = a x + b y + c (coordinates relative to the cloud's min corner).
struct HeightPlane {
  double a = 0, b = 0, c = 0;
  double at(double x, double y) const { return a * x + b * y + c; }
};

/// \brief Least-squares z = a x + b y + c of `m`, the slope pulled towards (a0, b0) with weight
///        `lambda` [weight m^2]. Needs m.w > 0.
HeightPlane fitHeightPlane(const Moments& m, double a0, double b0, double lambda);

/// \brief Valid points sorted by voxel key, their voxels and columns (written by Voxelizer).
///
/// Key layout: x | y | z bit fields, z lowest, so a column's voxels are consecutive and a
/// column's key is the voxel key >> shift_y.
struct VoxelGrid {
  std::uint64_t nx = 0, ny = 0, nz = 0;  // voxels per axis
  float min[3] = {0.f, 0.f, 0.f};        // min corner of the valid points (input frame)
  int shift_x = 0, shift_y = 0;
  std::uint64_t mask_y = 0, mask_z = 0;

  // Sorted position -> input index: the low slot_bits of keys[i] (packed) or order[i] is the
  // slot (valid point in input order), point_index[slot] the input index unless all_valid.
  bool packed = false;  // keys hold (voxel key << slot_bits | slot)
  int slot_bits = 32;   // packed: bits of the slot (32, fewer when the key needs more)
  bool all_valid = false;
  std::vector<std::uint64_t> keys;
  std::vector<std::uint32_t> order;
  std::vector<std::uint32_t> point_index;

  // Per valid point in key order: x y z relative to the cloud's min corner, three floats a
  // point (+ one spare float: build() stores four at a time), and its voxel.
  Buffer<float> sxyz;
  Buffer<std::uint32_t> pvox;

  // Per voxel, key order.
  Buffer<std::uint64_t> vkey;
  Buffer<std::uint32_t> vstart;      // CSR into the sorted points, size voxels + 1
  std::vector<float> vx, vy, vz;     // centroid
  std::vector<std::uint8_t> vflags;  // kFlat | kSeed
  std::vector<std::uint32_t> vcell;  // ground-model cell

  // Columns (x, y): runs of voxels.
  Buffer<std::uint64_t> col_key;    // voxel key >> shift_y
  Buffer<std::uint32_t> col_first;  // first voxel, size columns + 1

  // Flat voxels used for region growing (all of them for the global plane, the flat seed
  // candidates for the local model) and seed candidates, voxel ids in key order.
  Buffer<std::uint32_t> flat;
  Buffer<std::uint32_t> seeds;

  std::size_t points() const { return pvox.size(); }
  const float* xyz(std::size_t k) const { return sxyz.data() + 3 * k; }
  std::size_t voxels() const { return vkey.size(); }
  std::size_t columns() const { return col_key.size(); }
  std::uint32_t pointsIn(std::size_t v) const { return vstart[v + 1] - vstart[v]; }
  std::int32_t zOf(std::size_t v) const { return static_cast<std::int32_t>(vkey[v] & mask_z); }
};

/// \brief Cells of the local ground model (tile_size), with a border of one cell so 3 x 3
///        neighbourhoods need no bounds checks; one cell for the global plane.
struct CellGrid {
  std::uint64_t cell_vox = 1, ncx = 1, ncy = 1;
  std::vector<std::uint32_t> cell_of_x, cell_of_y;  // voxel x -> cell x * ncy, voxel y -> cell y
  std::vector<std::uint8_t> used;                   // holds voxels (Voxelizer)

  std::size_t count() const { return ncx * ncy; }
  /// \brief Sizes the grid for `nx` x `ny` voxels and fills the per-axis lookups.
  void setup(const VoxelGroundFilterParams& p, std::uint64_t nx, std::uint64_t ny);
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_VOXEL_GRID_H
