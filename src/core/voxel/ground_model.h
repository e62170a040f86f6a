// Private to the voxel filter: the ground model (one plane, or grown cell planes).
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_GROUND_MODEL_H
#define GROUND_FILTER_SRC_CORE_VOXEL_GROUND_MODEL_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/voxel_ground_filter_params.h"
#include "voxel/segments.h"
#include "voxel/voxel_grid.h"

namespace ground_filter {
namespace voxel {

/// \brief What GroundModel writes: the plane of every cell (one cell in global mode). Cells
///        without voxels keep what an earlier scan left (never read).
struct GroundModelResult {
  /// \brief Final plane per cell.
  UntouchedArray<HeightPlane> planes;
  /// \brief Per cell: cosine of the slope of its plane (vertical to normal distance).
  UntouchedArray<float> cos;
  /// \brief Final plane of cell c (cells holding voxels; any cell in global mode).
  const HeightPlane& plane(std::size_t c) const { return planes[c]; }
  /// \brief Cosine of the slope of plane(c).
  float cosine(std::size_t c) const { return cos[c]; }
};

/// \brief Step 6: the plane of every cell of a CellGrid (one cell: the global plane).
class GroundModel {
 public:
  /// \brief One plane for the whole scan (paper): `seg.plane`.
  void setGlobal(const SegmentResult& seg, GroundModelResult* out);
  /// \brief Cell planes grown outwards from the cell holding most of segment `seg.best`,
  ///        starting from its plane `seg.plane` (see the docs, "local ground model").
  void grow(const VoxelGroundFilterParams& p, const VoxelGrid& g, const CellGrid& cells,
            const SegmentResult& seg, GroundModelResult* out);

 private:
  /// Growth state of a cell.
  enum class CellState : std::uint8_t {
    kNew,         ///< not reached yet
    kQueued,      ///< waits in a queue
    kDone,        ///< finished without seeds (or never grown: border, out of reach)
    kDoneSeeded,  ///< finished with accepted seeds (its moments count for its neighbours)
  };
  struct Seed {
    float x, y, z, w;
  };
  struct Geometry {
    double cs = 1, lambda = 1, max_grad2 = 1;  // cell edge [m], slope prior weight, max slope^2
    std::uint32_t ncy = 1;                     // cells along y (border included)
    std::int64_t nb_off[9] = {};               // index offsets of the 3 x 3 neighbourhood
  };
  static bool finished(CellState s) { return s == CellState::kDone || s == CellState::kDoneSeeded; }
  /// Seed candidates per cell (CSR); returns the start cell.
  std::size_t bucketSeeds(const VoxelGrid& g, std::size_t cells, const SegmentResult& segs,
                          std::int64_t best);
  /// Every cell new (no seeds) except the border and cells out of reach.
  void resetCells(const CellGrid& cells);
  /// Marks the cells within kReachCells (along x and y) of a cell holding voxels in reach_.
  void markReach(const CellGrid& cells);
  /// Prediction of the start cell.
  HeightPlane startPlane(const VoxelGrid& g, const SegmentResult& segs, std::int64_t best,
                         std::size_t start, const HeightPlane& gp) const;
  /// Next cell with seeds that the growth did not reach (from *next on), queued as a new start.
  bool nextIsland(const CellGrid& cells, std::size_t* next, std::uint32_t* cell);
  /// Predicts, accepts seeds and fits cell t; returns whether it kept seeds.
  bool fitCell(const VoxelGroundFilterParams& p, std::uint32_t t);
  /// Queues the unfinished neighbours of t (near queue when t kept seeds).
  void queueNeighbours(std::uint32_t t, bool seeded);
  /// This scan's 3 x 3 seed sums of cell c (none yet: zero; nbsum_ is not cleared per scan).
  Moments sumsOf(std::size_t c) const { return nb_ok_[c] ? nbsum_[c] : Moments(); }

  Geometry geo_;

  std::vector<std::uint32_t> start_;         // seed candidates per cell (CSR)
  UntouchedArray<std::uint32_t> seg_count_;  // voxels of segment `best` per cell (bucketSeeds())
  std::vector<Seed> seeds_;
  // Per cell, written before read (UntouchedArray: RAM only for the cells a scan reaches).
  UntouchedArray<Moments> nbsum_;         // accepted seeds of the seeded cells of the 3 x 3 around
  std::vector<std::uint8_t> nb_ok_;       // nbsum_ of the cell holds this scan's sums
  UntouchedArray<HeightPlane> plane_;     // grown plane
  UntouchedArray<std::uint32_t> parent_;  // cell that queued it
  UntouchedArray<std::uint16_t> gap_;     // cells without seeds its prediction crossed
  std::vector<CellState> state_;
  UntouchedArray<std::uint32_t> queue_, queue_far_;  // cells to grow: next to seeds, others
  std::size_t near_end_ = 0, far_end_ = 0;           // entries in queue_, queue_far_
  std::vector<std::uint8_t> near_q_;                 // cell waits in queue_
  std::vector<std::uint8_t> near_y_;  // markReach(): a cell with voxels within reach along y
  std::vector<std::uint8_t> reach_;   // ... along x and y
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_GROUND_MODEL_H
