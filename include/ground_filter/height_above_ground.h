#ifndef GROUND_FILTER_HEIGHT_ABOVE_GROUND_H
#define GROUND_FILTER_HEIGHT_ABOVE_GROUND_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief Parameters of the ground surface behind the heights above ground. One line per field:
///        meaning [unit] (default). docs/height_above_ground.md gives the measurements.
struct GroundSurfaceParams {
  /// x/y cell edge of the surface [m] (1.0; 0.05 .. 100). Where the ground points' extent
  /// (plus radius) would need more than kMaxCells cells, the surface uses the smallest multiple
  /// of `cell` that fits (a scan several km wide).
  double cell = 1.0;
  /// A cell with no ground takes the inverse-distance-weighted elevation of the ground cells
  /// whose centres lie within this of its centre; farther: NaN [m] (5.0; 0 .. 1000, 0 = no fill).
  double radius = 5.0;
  /// The scan was taken from among its points (a LiDAR, a TLS, a registered ground-level
  /// cloud), so bushes and trunks cast occlusion shadows: a cell amid them is checked against
  /// the cells 3 to 5 cells out too. False for an airborne scan (the filters' scan_type says
  /// which; the nodelets and ground_filter_eval set it from there) (true).
  bool ground_level = true;
  /// Threads of heights(), 0 = all cores (1; 0 .. 256): the nodelets and ground_filter_eval
  /// pass the filter's own (FilterStats::threads). The heights are the same bit for bit for any
  /// count. build() runs on one thread (split, it was no faster on two cores:
  /// docs/height_above_ground.md, "Threads").
  int threads = 1;

  /// \brief Sets `ground_level` from a filter's FilterStats::scan_type: every scan type but
  ///        "airborne" was taken from among its points.
  void setScanType(const std::string& scan_type) { ground_level = scan_type != "airborne"; }

  /// \brief The most cells a surface holds (4 Mi: 2 km x 2 km at 1 m); see `cell`.
  static constexpr std::size_t kMaxCells = std::size_t{1} << 22;

  /// \brief Checks every field's range.
  /// \throws std::invalid_argument naming the first bad field, its value and its range.
  void validate() const;
};

/// \brief One occupied cell of a GroundSurface (a cell that holds at least one ground point and
///        is not a spike, see GroundSurface).
struct SurfaceCell {
  float x;               ///< cell centre x [m]
  float y;               ///< cell centre y [m]
  float z;               ///< ground elevation at the centre [m]
  std::uint32_t points;  ///< ground points in the cell [points]
  /// 0..1, n / (n + 3) * 1 / (1 + (rms / 0.05 m)^2): n the cell's ground points, rms the
  /// root-mean-square residual of their z around the cell's plane (or mean; the points the
  /// refit kept): more points and a smaller spread give a higher confidence; one point: 0.25.
  float confidence;
};

/// \brief Ground elevation over an x/y grid, built from the points a ground filter labelled
///        ground, and the height of any point above it.
///
/// The definition is the same for both methods (voxel, normal) and every scan type (single
/// scans, registered clouds, airborne tiles): only the filter's labels (1 = ground) and the
/// points' x/y/z enter, in the frame of the cloud (z up: the gravity frame where the filter ran
/// in one). The GPU path of the normal method gives the same labels as the CPU path, hence the
/// same heights: the surface is computed on the CPU from the labels in both cases.
///
/// In each occupied cell a least-squares plane z = a + b dx + c dy is fitted through the
/// cell's ground points when they are 3 or more and spread in x and y (else their mean z, no
/// slope); where the points' rms residual exceeds 0.02 m it is refitted once without the points
/// more than 2.5 rms off it; the cell's elevation is its plane at the cell centre. A cell
/// without ground points takes the inverse-distance-weighted (1/d^2) average of the planes of
/// the occupied cells within `radius`, each extrapolated to its centre (so a fill follows
/// slopes); none within `radius`: no elevation. An occupied cell more than 0.25 m above the
/// median of its occupied neighbours' planes (3 or more of the 8, extrapolated to its centre),
/// or more than 0.35 m above the median of those within 2 cells (12 or more of the 24), or, in a
/// ground-level scan (params.ground_level) where fewer than 12 of those 24 are occupied (an
/// occlusion shadow around it), more than 1.0 m above the median of the occupied cells 3 to 5
/// cells away (6 or more), is taken for low vegetation or an object labelled ground: it is
/// left out of cells() and filled like an empty cell (steps up to 0.25 m, kerbs, stay). The
/// elevation below (x, y) is the bilinear interpolation of the elevations at the four cell centres
/// around (x, y): continuous, exact on a plane. Cells without elevation drop out of it (the weights
/// of the others are renormalised); all four without: NaN. Negative heights (ditches, reflections
/// below the ground) are kept.
///
/// Buffers are kept between scans: after the first scan of a given extent, build() allocates
/// nothing. Not thread-safe for concurrent build(); heightAbove()/heights() are const.
class GroundSurface {
 public:
  /// \brief Builds the surface from the points labelled 1 (ground) in `labels` (one per point
  ///        of `cloud`; invalid points ignored).
  /// \throws std::invalid_argument when params.validate() fails or labels.size() differs
  ///         from cloud.size().
  void build(const CloudView& cloud, const std::vector<std::uint8_t>& labels,
             const GroundSurfaceParams& params);
  /// \brief z - ground elevation below (x, y); NaN where no ground cell lies within
  ///        params.radius (and for non-finite input).
  float heightAbove(float x, float y, float z) const;
  /// \brief heightAbove() of every point of `cloud` into `out` (resized to cloud.size(); NaN
  ///        for invalid points). Eight points at a time with AVX2 where the CPU and GF_SIMD
  ///        allow it: the same values as heightAbove(), bit for bit.
  void heights(const CloudView& cloud, std::vector<float>* out) const;
  /// \brief Ground elevation below (x, y); NaN where undefined (see heightAbove()).
  float elevation(float x, float y) const;
  /// \brief The occupied cells, in a deterministic order (row by row: y, then x ascending).
  const std::vector<SurfaceCell>& cells() const { return cells_; }
  /// \brief The cell edge in use [m]: params.cell, or a multiple of it for a very wide scan.
  double cellSize() const { return cell_; }

 private:
  // A cell's sums, in fours as the AVX2 path holds them: n, x, y, z | xx, xy, yy, zz | xz, yz.
  struct Accum {
    double n, sx, sy, sz, sxx, sxy, syy, szz, sxz, syz;
  };
  struct Fit {
    double z, gx, gy, rms;  // z relative to z_ref_ at the cell centre; slope [m/m]; residual
  };
  void chooseGrid(double min_x, double min_y, double max_x, double max_y, double radius,
                  double cell);
  bool gatherGround(const CloudView& cloud, const std::vector<std::uint8_t>& labels, float* bounds);
  void cellOffsets();
  void accumulate(bool refit);
  template <class Run>
  void accumulateWith(bool refit);
  void accumulateAvx2(bool refit);
  Fit fitCell(const Accum& a) const;
  void dropSpikes();
  bool medianSpike(std::size_t s, int i, int j, int* ka) const;
  bool shadowSpike(std::size_t s, int i, int j) const;
  void blockLows();
  static constexpr int kBlock = 4;  // cells: edge of a block of block_low_
  void fill();

  double cell_ = 1.0, radius_ = 5.0;
  bool ground_level_ = true;
  int threads_ = 1;            // params.threads resolved (heights())
  double z_ref_ = 0.0;         // z the sums are taken from
  float x0_ = 0.f, y0_ = 0.f;  // lower-left corner of the grid
  int nx_ = 0, ny_ = 0;
  int bnx_ = 0, bny_ = 0;   // blocks of block_low_
  std::size_t ground_ = 0;  // finite ground points of the last build
  // Per finite ground point (cloud order): x, y, z; x, y relative to the cell centre after
  // cellOffsets().
  std::vector<float> px_, py_, pz_;
  std::vector<std::int32_t> pslot_;       // per ground point: its grid cell
  std::vector<std::uint32_t> run_start_;  // first ground point of each run of points in one cell
  std::vector<std::int32_t> run_slot_;    // per run: its occupied cell
  std::vector<std::int32_t> slot_;        // per grid cell: its occupied-cell index, or -1
  std::vector<float> centre_;             // per grid cell: elevation at the centre, NaN: none
  std::vector<float> wsum_;     // per grid cell: fill weights (fill()); before it z_ (dropSpikes())
  std::vector<float> gy_grid_;  // per grid cell: gy_ (dropSpikes(); centre_ holds gx_ then)
  std::vector<std::uint32_t> occupied_;  // grid cell of each occupied cell, first seen first
  std::vector<Accum> acc_;               // per occupied cell
  std::vector<Fit> fit_;                 // per occupied cell
  std::vector<float> z_, gx_, gy_;       // per occupied cell: plane (absolute z at the centre)
  std::vector<std::uint8_t> flags_;      // per occupied cell: refit, spike bits
  std::vector<std::uint32_t> count_;     // per occupied cell: its ground points
  std::vector<float> block_low_;         // per block of kBlock x kBlock cells: lowest z_
  std::vector<float> kernel_;            // 1 / d^2 of the fill window, 0 beyond the radius
  std::vector<SurfaceCell> cells_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_HEIGHT_ABOVE_GROUND_H
