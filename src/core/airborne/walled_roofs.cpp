// Step 3c of the airborne mode's surface (morph_ground.h): roofs wider than the opening, found
// by the walls they stand on.

#include <algorithm>
#include <cmath>
#include <limits>

#include "airborne/morph_ground.h"

namespace ground_filter {

double MorphGround::planeRms(const std::vector<std::int32_t>& cells) const {
  // z = a + b x + c y by least squares over the cells with a return, about the first cell.
  const int x0 = cells[0] % nx_, y0 = cells[0] / nx_;
  double m[3][4] = {};
  for (const std::int32_t i : cells) {
    if (std::isnan(zmin_[i])) continue;
    const double v[3] = {1.0, static_cast<double>(i % nx_ - x0), static_cast<double>(i / nx_ - y0)};
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) m[r][k] += v[r] * v[k];
      m[r][3] += v[r] * zmin_[i];
    }
  }
  if (m[0][0] < 3.0) return std::numeric_limits<double>::infinity();
  for (int p = 0; p < 3; ++p) {  // Gauss-Jordan; the region spans two axes, so no zero pivot
    if (std::fabs(m[p][p]) < 1e-9) return std::numeric_limits<double>::infinity();
    for (int r = 0; r < 3; ++r) {
      if (r == p) continue;
      const double f = m[r][p] / m[p][p];
      for (int k = p; k < 4; ++k) m[r][k] -= f * m[p][k];
    }
  }
  const double a = m[0][3] / m[0][0], b = m[1][3] / m[1][1], cc = m[2][3] / m[2][2];
  double ss = 0.0, count = 0.0;
  for (const std::int32_t i : cells) {
    if (std::isnan(zmin_[i])) continue;
    const double e = zmin_[i] - (a + b * (i % nx_ - x0) + cc * (i / nx_ - y0));
    ss += e * e;
    count += 1.0;
  }
  return std::sqrt(ss / count);
}

bool MorphGround::walledOutside(float wall, float gap_wall) {
  // The cells outside the region (frontier_, region_): reached from the raster's edge without
  // crossing it. The others are its holes: a pit in a yard, a light well in a roof. Everything
  // beyond the region's bounding box is outside, so the search starts on the box grown by a cell
  // and stays in it: its cost follows the region, not the raster. outside_ is all 0 on entry
  // and left so.
  const std::int32_t region = region_[frontier_[0]];
  int x0 = nx_, x1 = 0, y0 = ny_, y1 = 0;
  for (const std::int32_t i : frontier_) {
    x0 = std::min(x0, i % nx_);
    x1 = std::max(x1, i % nx_);
    y0 = std::min(y0, i / nx_);
    y1 = std::max(y1, i / nx_);
  }
  x0 = std::max(0, x0 - 1);
  y0 = std::max(0, y0 - 1);
  x1 = std::min(nx_ - 1, x1 + 1);
  y1 = std::min(ny_ - 1, y1 + 1);
  outside_queue_.clear();
  auto reach = [&](std::int32_t j) {
    if (region_[j] == region || outside_[j]) return;
    outside_[j] = 1;
    outside_queue_.push_back(j);
  };
  for (int x = x0; x <= x1; ++x) {
    reach(y0 * nx_ + x);
    reach(y1 * nx_ + x);
  }
  for (int y = y0; y <= y1; ++y) {
    reach(y * nx_ + x0);
    reach(y * nx_ + x1);
  }
  for (std::size_t head = 0; head < outside_queue_.size(); ++head) {
    forNeighbours(outside_queue_[head], [&](std::int32_t j) {
      const int x = j % nx_, y = j / nx_;
      if (x >= x0 && x <= x1 && y >= y0 && y <= y1) reach(j);
    });
  }
  // Its border and walls again, on the outside only (beyond the box every cell is outside).
  std::size_t border = 0, walls = 0;
  for (const std::int32_t i : frontier_) {
    forNeighbours(i, [&](std::int32_t j) {
      if (!outside_[j] || object_[j] || !known_[j]) return;
      const float step = stepLimit(i, j, wall, gap_wall);
      if (std::fabs(zfill_[j] - zfill_[i]) < step) return;
      ++border;
      walls += zfill_[i] - zfill_[j] >= step;
    });
  }
  for (const std::int32_t j : outside_queue_) outside_[j] = 0;
  return border > 0 && static_cast<double>(walls) >= kWalledShare * static_cast<double>(border);
}

bool MorphGround::keptOnlyBySteepPass() const {
  // object1_ holds the first opening's objects only when the steep-terrain pass ran.
  if (object1_.size() != zfill_.size()) return false;
  std::size_t objects = 0;
  for (const std::int32_t i : frontier_) objects += object1_[i] != 0;
  return static_cast<double>(objects) >=
         kSmallRoofObjectShare * static_cast<double>(frontier_.size());
}

bool MorphGround::flatRoof() {
  if (planeRms(frontier_) <= kRoofRms) return true;
  // A roof in parts at several heights (a raised bay, a lower wing): the region cut at steps of
  // kPartStep or more; its parts of kMinPartCells or more cells with a return that lie within
  // kRoofRms of their own planes must hold kFlatPartShare of its cells with a return.
  std::size_t with_return = 0, in_flat = 0;
  part_.resize(zfill_.size());
  for (const std::int32_t i : frontier_) part_[i] = -1;
  const std::int32_t region = region_[frontier_[0]];
  for (const std::int32_t seed : frontier_) {
    if (part_[seed] >= 0) continue;
    part_cells_.assign(1, seed);
    part_[seed] = seed;
    std::size_t returns = 0;
    for (std::size_t head = 0; head < part_cells_.size(); ++head) {
      const std::int32_t i = part_cells_[head];
      returns += !std::isnan(zmin_[i]);
      forNeighbours(i, [&](std::int32_t j) {
        if (region_[j] != region || part_[j] >= 0 ||
            std::fabs(zfill_[j] - zfill_[i]) >= kPartStep) {
          return;
        }
        part_[j] = seed;
        part_cells_.push_back(j);
      });
    }
    with_return += returns;
    if (returns >= kMinPartCells && planeRms(part_cells_) <= kRoofRms) in_flat += returns;
  }
  return static_cast<double>(in_flat) >= kFlatPartShare * static_cast<double>(with_return);
}

void MorphGround::markNearReturns(int rings) {
  const std::size_t n = zmin_.size();
  known_.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) known_[i] = !std::isnan(zmin_[i]);
  for (int ring = 0; ring < rings; ++ring) {
    for (std::size_t i = 0; i < n; ++i) {
      if (known_[i] != 1) continue;
      forNeighbours(static_cast<std::int32_t>(i), [&](std::int32_t j) {
        if (known_[j] == 0) known_[j] = 2;  // reached in this ring: grows from it in the next
      });
    }
    for (std::uint8_t& m : known_) m = m != 0;
  }
}

MorphGround::RegionBorder MorphGround::floodRegion(std::int32_t seed, float wall, float gap_wall) {
  RegionBorder b;
  frontier_.assign(1, seed);
  region_[seed] = seed;
  for (std::size_t head = 0; head < frontier_.size(); ++head) {
    const std::int32_t i = frontier_[head];
    const int x = i % nx_, y = i / nx_;
    b.open += x == 0 || y == 0 || x + 1 == nx_ || y + 1 == ny_;
    forNeighbours(i, [&](std::int32_t j) {
      b.against_roof += object_[j] == kRoofCell && zfill_[j] > zfill_[i];
      b.open += !object_[j] && !known_[j];
      if (object_[j] || !known_[j]) return;  // an object's terrain comes from this region
      const float other = zfill_[j];
      const float step = stepLimit(i, j, wall, gap_wall);
      if (std::fabs(other - zfill_[i]) < step) {
        if (region_[j] < 0) {
          region_[j] = seed;
          frontier_.push_back(j);
        }
        return;
      }
      ++b.border;
      b.walls += zfill_[i] - other >= step;
    });
  }
  return b;
}

void MorphGround::dropRoof(float gap_wall) {
  for (const std::int32_t i : frontier_) object_[i] = kRoofCell;
  // A cell without a return along its edge whose fill drops to a neighbour by a gap wall holds
  // the wall the scan did not see: not ground either.
  for (const std::int32_t i : frontier_) {
    forNeighbours(i, [&](std::int32_t j) {
      if (object_[j] || !std::isnan(zmin_[j])) return;
      bool on_wall = false;
      forNeighbours(j, [&](std::int32_t k) {
        on_wall = on_wall || (!object_[k] && zfill_[j] - zfill_[k] >= gap_wall);
      });
      if (on_wall) object_[j] = kRoofCell;
    });
  }
}

void MorphGround::dropWalledRoofs(double c, int rmax) {
  // A roof wider than the opening (2 x window) survives it as terrain. Its border tells it from
  // terrain: walls, a drop of a storey or more from one cell to the next, all round it, and one
  // plane through it (or a few, one per part). Regions of terrain cells joined by smaller steps,
  // wider than the opening takes (or narrower ones that only the steep-terrain pass kept:
  // keptOnlyBySteepPass()), standing on walls along kWalledShare of their outer border and that
  // flat, become objects. The raster's edge, object cells (their terrain is filled from
  // this very region) and cells far from any return (outside a clipped tile's footprint, a
  // lake: the fill joins anything across them) neither join a region nor border it.
  const float wall = static_cast<float>(std::max(kWallDrop, 2.0 * c));
  const float gap_wall = static_cast<float>(kGapWallSlope * c);
  const std::size_t n = zfill_.size();
  const std::size_t min_cells = static_cast<std::size_t>(3.14159 * rmax * rmax);
  const std::size_t min_small =
      std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(kSmallRoofArea / (c * c))));
  markNearReturns(2);
  outside_.assign(n, 0);
  bool changed = false;
  // A roof dropped here can uncover a lower part of the same building (a wing below a raised
  // bay): its edges against that roof are no border, so the regions are judged again while a
  // pass drops a roof. A region that meets such a roof must lie inside the raster and among
  // returns: ground at a hall's foot goes on beyond the tile.
  for (int pass = 0; pass < kRoofPasses; ++pass) {
    region_.assign(n, -1);
    bool dropped = false;
    for (std::size_t seed = 0; seed < n; ++seed) {
      if (object_[seed] || !known_[seed] || region_[seed] >= 0) continue;
      const RegionBorder b = floodRegion(static_cast<std::int32_t>(seed), wall, gap_wall);
      const std::size_t size = frontier_.size();
      if ((size < min_cells && (size < min_small || !keptOnlyBySteepPass())) || b.border == 0 ||
          (b.against_roof > 0 && b.open > 0) ||
          static_cast<double>(b.walls) < kWalledShare * static_cast<double>(b.border) ||
          !flatRoof() || !walledOutside(wall, gap_wall)) {
        continue;
      }
      dropRoof(gap_wall);
      dropped = true;
    }
    changed = changed || dropped;
    if (!dropped) break;
  }
  if (changed) surfaceWithoutObjects();
}

}  // namespace ground_filter
