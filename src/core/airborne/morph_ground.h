#ifndef GROUND_FILTER_SRC_CORE_AIRBORNE_MORPH_GROUND_H
#define GROUND_FILTER_SRC_CORE_AIRBORNE_MORPH_GROUND_H

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief Settings of the morphological ground surface (both filters' `morph_*` parameters).
struct MorphGroundSettings {
  double cell = 1.0;       ///< raster cell edge [m]
  double slope = 0.1;      ///< terrain slope allowed by the opening, rise / run [1]
  double window = 18.0;    ///< largest opening radius [m] (about the widest building)
  double threshold = 0.5;  ///< max |z - surface| of a ground point on flat ground [m]
  double scale = 1.25;     ///< added to threshold per unit of surface gradient [m]
};

/// \brief Low outliers: a cell's lowest return with at least `min_neighbours` others within
///        `radius` [m] (horizontally), all more than `drop` [m] above it, and no other return
///        within `alone` [m] (horizontally) less than `drop` above it, is left out of the minimum
///        raster (ISPRS pooled F1 within 0.03 for radius 2-4 m, drop 1-3 m, 1-10 neighbours).
///        Constants, not parameters (MorphGround::kLowOutlier).
struct LowOutlierRule {
  double radius = 3.0;     ///< [m] neighbourhood of the cell's lowest return
  double drop = 2.0;       ///< [m] all those neighbours lie more than this above it
  int min_neighbours = 6;  ///< at least this many of them
  /// [m] and no return within this lies less than `drop` above it: ground is a surface, so
  /// even the sparse ground returns under a dense canopy have others at their height within a
  /// few metres; an outlier has none.
  double alone = 10.0;
};

/// \brief Airborne ground model after SMRF (Pingel, Clarke and McBride 2013), written from its
///        description: a minimum-elevation raster (without low outliers) with its gaps filled,
///        opened with disks of growing radius (cells that drop by more than slope x radius at a
///        step are objects; then steep terrain's own allowance, and flat regions wider than the
///        opening that stand on walls all round: roofs), the raster without the object cells
///        filled again, and per point the test |z - bilinear surface| <= threshold + scale x
///        gradient. Works on any cloud; meant
///        for nadir scans, where the lowest return of a cell is mostly ground. Owns its buffers
///        (reused across scans).
class MorphGround {
 public:
  /// \brief Labels every point of `cloud`: 1 ground, 0 not (invalid points 0). Returns the
  ///        number of valid points. The raster cell grows when the cloud's x/y extent would need
  ///        more than kMaxCells cells, or more than kMaxCellsPerPoint cells a point.
  std::size_t run(const CloudView& cloud, const MorphGroundSettings& s,
                  std::vector<std::uint8_t>* labels);

  /// \brief Upper limit on raster cells (memory and time bound for huge extents).
  static constexpr std::size_t kMaxCells = std::size_t{1} << 22;
  /// \brief The raster also holds at most this many cells per valid point (at least kMinCells):
  ///        beyond it the cell grows, as for kMaxCells.
  static constexpr double kMaxCellsPerPoint = 16.0;
  static constexpr std::size_t kMinCells = 4096;
  /// \brief The low-outlier rule in force.
  static constexpr LowOutlierRule kLowOutlier{};
  /// \brief Steep-terrain passes at most (the second measures the terrain slope again on the
  ///        first's surface, which keeps more of a crest; skipped when nothing changes).
  static constexpr int kSteepPasses = 2;
  /// \brief Walled roofs (dropWalledRoofs()): a drop of at least this from one cell to the next
  ///        is a wall [m] (a storey; at least 2 cells' rise on coarse rasters). Plateau of the
  ///        generated halls: 1.5-5 m; no real tile changes anywhere on it.
  static constexpr double kWallDrop = 2.5;
  /// \brief ... where one of the two cells has no return, a fill steeper than this (rise / run)
  ///        is a wall: the one the scan did not see (plateau 0.5-2).
  static constexpr double kGapWallSlope = 1.0;
  /// \brief ... a region is a roof when it stands on walls along at least this share of its
  ///        border (plateau 0.75-0.9; flat terrain regions of the real tiles reach 0.75 only
  ///        where they are far from planar) ...
  static constexpr double kWalledShare = 0.8;
  /// \brief ... and its cells' minima lie within this RMS of one plane [m] (plateau 0.2-1.0).
  static constexpr double kRoofRms = 0.3;
  /// \brief ... or, a roof in parts at several heights, the region cut at steps of at least
  ///        this [m] ...
  static constexpr double kPartStep = 0.5;
  /// \brief ... gives parts of at least this many cells with a return, each within kRoofRms of
  ///        its own plane ...
  static constexpr std::size_t kMinPartCells = 50;
  /// \brief ... that hold at least this share of the region's cells with a return.
  static constexpr double kFlatPartShare = 0.9;
  /// \brief A region narrower than the opening is judged too where it covers at least this
  ///        area [m2] and the first opening (SMRF's slope allowance) took at least
  ///        kSmallRoofObjectShare of its cells for objects: only the steep-terrain pass kept it,
  ///        whose allowance a roof next to a steep fill (a strip without returns running to its
  ///        edge) or a building on a slope gets too. Plateau 100-200 m2 (share 0.5) and 0.25-0.75
  ///        (100 m2): below 100 m2 terraces of ISPRS samp41 go, above 200 m2 the generated
  ///        buildings on slopes stay ground (docs/evaluation.md, "Parts narrower than the
  ///        opening, and strips without returns").
  static constexpr double kSmallRoofArea = 150.0;
  static constexpr double kSmallRoofObjectShare = 0.5;
  /// \brief Passes over the regions at most: a pass after one that dropped a roof judges the
  ///        lower parts it uncovered (a building of three levels needs three).
  static constexpr int kRoofPasses = 3;

 private:
  void fill(std::vector<float>* z);  // fill NaN cells (nearest rings, then Laplace sweeps)
  void erode(const std::vector<float>& in, int r, bool dilate, std::vector<float>* out);
  // Progressive opening of zfill_ up to radius rmax: object cells into `object`; the allowed
  // slope is `slope`, or per cell max(slope, (*allow)[cell]) when allow is given.
  void openObjects(const MorphGroundSettings& s, double c, int rmax,
                   const std::vector<float>* allow, std::vector<std::uint8_t>* object);
  void surfaceWithoutObjects();        // dem_ = zmin_ without object_ cells, gaps filled
  void terrainSlope(double c, int w);  // tslope_ from dem_ across +-w cells
  void joinTerrain(const MorphGroundSettings& s, double c);  // second-pass cells joined to terrain
  void dropLowOutliers(const CloudView& cloud, double c);    // zmin_ without low outliers
  // Terrain regions wider than the opening, flat and walled all round: objects (roofs).
  void dropWalledRoofs(double c, int rmax);
  // Calls f(j) for each 4-neighbour j of cell i inside the raster, in the order -x, +x, -y, +y.
  template <class F>
  void forNeighbours(std::int32_t i, F&& f) const {
    const int x = i % nx_, y = i / nx_;
    if (x > 0) f(i - 1);
    if (x + 1 < nx_) f(i + 1);
    if (y > 0) f(i - nx_);
    if (y + 1 < ny_) f(i + nx_);
  }
  // known_ = 1 on the cells with a return and the `rings` 4-neighbour rings around them.
  void markNearReturns(int rings);
  // RMS distance of the minima of `cells` from their least-squares plane.
  double planeRms(const std::vector<std::int32_t>& cells) const;
  // Whether the region (frontier_, region_) is a roof's: within kRoofRms of one plane, or in
  // flat parts at several heights (kPartStep, kMinPartCells, kFlatPartShare).
  bool flatRoof();
  // Whether kSmallRoofObjectShare of the region's cells were objects to the first opening
  // (object1_; false where the steep-terrain pass did not run).
  bool keptOnlyBySteepPass() const;
  // A region's border as floodRegion() counts it: steps of a wall or more to the cells around,
  // and how many of them drop (walls); edges up to a roof dropped before; cell sides on the
  // raster's edge or next to cells far from any return.
  struct RegionBorder {
    std::size_t border = 0, walls = 0, against_roof = 0, open = 0;
  };
  // The step between neighbouring cells i and j that is a border, not a join: `wall`, or
  // `gap_wall` where either has no return (the fill ramps across the gap: a ramp steeper than 45
  // degrees there is the wall the scan did not see).
  float stepLimit(std::int32_t i, std::int32_t j, float wall, float gap_wall) const {
    return std::isnan(zmin_[i]) || std::isnan(zmin_[j]) ? gap_wall : wall;
  }
  // The region of terrain cells joined to `seed` by steps under `wall` (`gap_wall` where a cell
  // has no return) into frontier_ and region_ (= seed), and its border.
  RegionBorder floodRegion(std::int32_t seed, float wall, float gap_wall);
  // The region (frontier_) becomes roof cells, and with it the cells without a return along its
  // edge that stand a gap wall above a neighbour.
  void dropRoof(float gap_wall);
  // Whether the region (frontier_, region_) stands on walls (`wall`, `gap_wall` across a cell
  // without a return) along kWalledShare of its outer border: its holes left out.
  bool walledOutside(float wall, float gap_wall);
  // Whether point m (cell x, y) has no other return within kLowOutlier.alone that is less than
  // kLowOutlier.drop above it.
  bool aloneAtItsHeight(const CloudView& cloud, double c, int x, int y, std::int32_t m) const;

  int nx_ = 0, ny_ = 0;
  std::vector<std::int32_t> cell_of_;                // per point: cell index, -1 invalid
  std::vector<std::int32_t> cell_start_, cell_pts_;  // points bucketed by cell
  std::vector<float> zmin_, zfill_, tmp_, eroded_, opened_, dem_, grad_, tslope_;
  std::vector<float> pad_;  // erode(): one row between two sentinels
  // object_: 0 terrain, 1 an object, kRoofCell a walled roof (dropWalledRoofs()).
  static constexpr std::uint8_t kRoofCell = 2;
  std::vector<std::uint8_t> object_, object1_, prev_object_, known_;
  std::vector<std::int32_t> frontier_, next_, gaps_, region_;
  std::vector<std::int32_t> part_, part_cells_;  // flatRoof(): part per cell, one part's cells
  std::vector<std::uint8_t> outside_;            // walledOutside(): reached; 0 between calls
  std::vector<std::int32_t> outside_queue_;
  std::vector<float> fill_vals_;  // fill(): the values of one ring
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_AIRBORNE_MORPH_GROUND_H
