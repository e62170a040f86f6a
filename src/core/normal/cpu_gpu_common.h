#ifndef GROUND_FILTER_SRC_CORE_NORMAL_CPU_GPU_COMMON_H
#define GROUND_FILTER_SRC_CORE_NORMAL_CPU_GPU_COMMON_H

// Helpers and constants of the normal filter that the CPU code and the CUDA pipeline (cuda/src)
// must compute alike: one source, compiled by the host compiler and by nvcc.

#include <math.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

#include "common/host_device.h"
#include "knn/pca_cpu_gpu_common.h"

namespace ground_filter {
namespace normal {

/// \brief Integer cell coordinate of `v` on a grid starting at `lo`, clamped to 32 bits:
///        floor((v - lo) * inv_cell) in [0, 2^32 - 1], 0 for NaN.
GF_HOST_DEVICE inline std::uint32_t cellIndex(double v, double lo, double inv_cell) {
  // floor(c) > 0 exactly when c >= 1, and from there truncation is floor: the same values as
  // with floor(), which x86-64 without SSE4.1 computes in a branchy sequence (a KITTI frame's
  // column keys took 2.6 times as long).
  const double c = (v - lo) * inv_cell;
  if (!(c >= 1.0)) return 0;
  if (c >= 4294967295.0) return 4294967295U;
  return static_cast<std::uint32_t>(c);
}

/// \brief Spreads the 32 bits of v over the even bits of a 64-bit word (Morton interleave).
GF_HOST_DEVICE inline std::uint64_t spreadBits(std::uint64_t v) {
  v &= 0xffffffffULL;
  v = (v | (v << 16)) & 0x0000ffff0000ffffULL;
  v = (v | (v << 8)) & 0x00ff00ff00ff00ffULL;
  v = (v | (v << 4)) & 0x0f0f0f0f0f0f0f0fULL;
  v = (v | (v << 2)) & 0x3333333333333333ULL;
  v = (v | (v << 1)) & 0x5555555555555555ULL;
  return v;
}

/// \brief Morton key of the grid column (cx, cy).
GF_HOST_DEVICE inline std::uint64_t columnKey(std::uint32_t cx, std::uint32_t cy) {
  return spreadBits(cx) | (spreadBits(cy) << 1);
}

/// \brief Most sampled points a grid column gives (SampleStage): 4 k. The k nearest sampled
///        neighbours of a point then cover at least about a quarter of its 0.1 m column (about
///        5 cm across), more than the range noise, however densely a station samples the ground
///        near its tripod. Generated TLS stations of 10-50 M points (seeds 1-3): F1 within 0.002
///        of each other for caps of 2 k-8 k, where no cap, or 16 k, fell to 0.89 at 50 M
///        (docs/normal_method.md#dense-columns-tls-stations). No column of the KITTI frames
///        holds 2 x 4 k points: their labels are those of the plain stride.
GF_HOST_DEVICE inline int columnSampleCap(int k) { return 4 * k; }

/// \brief Largest sample_stride (its range in normal_params.def).
constexpr int kMaxSampleStride = 16;

/// \brief The next sample_stride of both sparse-lines rules: twice `stride`, at most
///        kMaxSampleStride.
inline int doubledStride(int stride) {
  return 2 * stride < kMaxSampleStride ? 2 * stride : kMaxSampleStride;
}

/// \brief The stride to redo a scan's normals with, or 0 to keep them: fewer than `min_share`
///        of its `sampled` points got a ground-candidate neighbourhood (`candidates`), and
///        `stride` can still double. On a sparse spinning sensor (a VLP-16 at 0.2 deg a firing:
///        rings 2 deg apart) the K nearest sampled neighbours of a point lie on its own scan
///        line, a line has no plane, and almost no point becomes a candidate (0.3-3.4 % of them
///        on generated street scans); sampling every 2nd point more spaces the samples along a
///        line and their neighbourhoods reach the next line. Grass and slopes can keep the share
///        above 5 % on such a sensor, so this is the safety net behind the measured lines
///        (scan_lines.h, max_line_ratio), not the main rule
///        (docs/normal_method.md#sparse-scan-lines-max_line_ratio-min_candidate_share). The CPU
///        filter and the GPU pipeline decide alike, on the same count.
inline int sparseLinesStride(std::size_t candidates, std::size_t sampled, double min_share,
                             int stride) {
  // A share of fewer sampled points says little (a tiny or degenerate cloud: every point in one
  // place); the smallest sparse sensor's scan samples over 10,000.
  constexpr std::size_t kMinSampled = 1000;
  if (!(min_share > 0.0) || sampled < kMinSampled || stride >= kMaxSampleStride) return 0;
  if (static_cast<double>(candidates) >= min_share * static_cast<double>(sampled)) return 0;
  return doubledStride(stride);
}

/// \brief Appends the FilterStats note of a scan redone with a wider stride (CPU and GPU
///        alike) to `note` ("; " first when it is not empty), in place: no allocation once the
///        string has room.
inline void appendSparseLinesNote(int from, int to, std::string* note) {
  char text[200];
  std::snprintf(text, sizeof text,
                "%ssample_stride %d -> %d: under min_candidate_share of the sampled points had a "
                "ground-candidate normal (scan lines far apart; sample_stride %d saves the first "
                "pass)",
                note->empty() ? "" : "; ", from, to, to);
  note->append(text);
}

/// \brief The sample of one grid column of `count` points (SampleStage; the GPU's sample
///        kernels): 0 keeps the segment's `stride` (every stride-th point of the segment); a
///        column of more than `stride * cap` points is sampled every returned step from its first
///        point instead, at most `cap` points, so that the k nearest sampled neighbours of a point
///        in a very dense column (a TLS station near its tripod) span more than the range noise.
GF_HOST_DEVICE inline std::size_t columnSampleStep(std::size_t count, std::size_t stride,
                                                   std::size_t cap) {
  if (cap == 0 || count <= stride * cap) return 0;
  return (count + cap - 1) / cap;
}

/// \brief Position in the ordered cloud of the j-th sampled point: sampled[j], or j when every
///        point is sampled (`sampled` null). The sample's list ends with the cloud's size, so
///        j = m gives the end of the last sampled point's run.
GF_HOST_DEVICE inline std::size_t sampledPosition(const std::uint32_t* sampled, std::size_t j) {
  return sampled ? sampled[j] : j;
}

/// \brief Small deterministic generator (splitmix64): the same sequence on every platform,
///        library and device, so RANSAC draws the same samples on the CPU and the GPU.
struct SplitMix64 {
  static constexpr std::uint64_t kStep = 0x9e3779b97f4a7c15ULL;
  std::uint64_t state;
  GF_HOST_DEVICE explicit SplitMix64(std::uint64_t seed) : state(seed) {}
  GF_HOST_DEVICE std::uint64_t next() {
    std::uint64_t z = (state += kStep);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  GF_HOST_DEVICE std::size_t below(std::size_t n) { return static_cast<std::size_t>(next() % n); }
  /// \brief Skips `draws` values (as many next() calls): the GPU scores several RANSAC draws at
  ///        once, each from its own place in the sequence.
  GF_HOST_DEVICE void skip(std::uint64_t draws) { state += draws * kStep; }
};

constexpr std::uint64_t kRansacSeed = 0x67f1a3c5d2b9e481ULL;  // fixed: reproducible output

/// \brief The base seed of a scan's RANSAC draws for the `ransac_seed` parameter: 0 gives
///        kRansacSeed (the labels before the parameter existed), others a different stream.
GF_HOST_DEVICE inline std::uint64_t ransacBaseSeed(std::uint32_t user_seed) {
  return kRansacSeed ^ (static_cast<std::uint64_t>(user_seed) * 0xd1b54a32d192ed03ULL);
}
/// Lanes of a RANSAC plane's least-squares sums: point j of the plane's list adds into lane
/// j mod kPlaneSumLanes, the lanes are added in order at the end. The GPU sums with one thread
/// per lane (its plane blocks have this many threads), so the CPU and the GPU round alike.
constexpr int kPlaneSumLanes = 128;
constexpr unsigned int kRansacEvalPoints = 2048;  // hypotheses are scored on at most this many
// Fewer voted points: the tile uses the cloud-wide plane. 3 (the fewest a plane needs): even a
// few voted points of a far tile follow its ground better than the cloud-wide plane, which the
// near road dominates (docs/normal_method.md, "Sparse tiles").
constexpr unsigned int kMinTilePoints = 3;

// A tile whose own plane stands more than this above the median of its neighbouring tiles'
// own planes, all taken at its centre, is the top of an object (a car in the next lane, its
// bonnet and roof 0.9-1.5 m up, whose tile holds little else: the blind zone and the car's own
// shadow hide the road around it). The tile is labelled against that median neighbour's plane.
// Ground does not step this much between 4 m tiles: kerbs are 0.1-0.25 m, and a slope is in
// both planes. 0.75 m: the middle of 0.5-1.0 m, below a car's bonnet and above a kerb with the
// slope error of planes carried 4 m; the dev groups do not move from 0.75 to 3.0 m
// (docs/normal_method.md, "Raised tiles") [m].
constexpr double kRaisedTileStep = 0.75;
// Neighbouring tiles (of 8) with their own plane that the raised-tile test needs.
constexpr int kRaisedTileLeast = 3;
/// \brief Neighbour v (0..7) of a tile: its offsets dx, dy in -1..1, x-major, the tile itself
///        skipped; the order in which both the CPU and the GPU visit them.
GF_HOST_DEVICE inline void tileNeighbour(int v, int* dx, int* dy) {
  const int cell = v < 4 ? v : v + 1;
  *dx = cell / 3 - 1;
  *dy = cell % 3 - 1;
}

/// \brief The sort key tx << ybits | ty of neighbour v of the tile (tx, ty) (tileNeighbour());
///        false where it lies off the grid.
GF_HOST_DEVICE inline bool tileNeighbourKey(std::uint64_t tx, std::uint64_t ty, int ybits, int v,
                                            std::uint64_t* key) {
  int dx, dy;
  tileNeighbour(v, &dx, &dy);
  const std::uint64_t y_max = (std::uint64_t{1} << ybits) - 1;
  if ((dx < 0 && tx == 0) || (dy < 0 && ty == 0) || (dy > 0 && ty == y_max)) return false;
  *key = ((tx + dx) << ybits) | (ty + dy);
  return true;
}

/// \brief Index of the tile whose sort key is `want` among `n` tiles in key order
///        (key_at(i): tile i's key), -1 when no tile has it.
template <class KeyAt>
GF_HOST_DEVICE inline std::int64_t findTile(KeyAt key_at, std::uint64_t n, std::uint64_t want) {
  std::uint64_t lo = 0, hi = n;
  while (lo < hi) {
    const std::uint64_t mid = (lo + hi) / 2;
    if (key_at(mid) < want) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return lo < n && key_at(lo) == want ? static_cast<std::int64_t>(lo) : -1;
}

/// \brief z at (x, y) of the plane n . (q - o) + d = 0 (a tile plane: n_z within the angle
///        window, never 0).
GF_HOST_DEVICE inline double planeZAt(const double n[3], double d, const double o[3], double x,
                                      double y) {
  return o[2] - ((n[0] * (x - o[0]) + n[1] * (y - o[1])) + d) / n[2];
}

/// \brief The raised-tile test: given a tile's plane height `zt` at its centre and its
///        neighbours' `zs[0..k)` there (in tileNeighbour() order), the position in `zs` of
///        the median neighbour (the upper one of an even count; ties in visiting order) when
///        k >= kRaisedTileLeast and the tile stands more than kRaisedTileStep above it, else -1.
GF_HOST_DEVICE inline int raisedTileMedian(double zt, const double* zs, int k) {
  if (k < kRaisedTileLeast) return -1;
  int order[8];
  for (int i = 0; i < k; ++i) {  // insertion sort of at most 8: stable, the same on both sides
    int j = i;
    while (j > 0 && zs[order[j - 1]] > zs[i]) {
      order[j] = order[j - 1];
      --j;
    }
    order[j] = i;
  }
  const int mid = order[k / 2];
  return zt - zs[mid] > kRaisedTileStep ? mid : -1;
}

/// \brief Squared horizontal distance from (sx, sy) to (px, py) [m^2].
GF_HOST_DEVICE inline double horizontalDistance2(double sx, double sy, double px, double py) {
  const double rx = sx - px, ry = sy - py;
  return rx * rx + ry * ry;
}

/// \brief Horizontal distance from (sx, sy) to (px, py) [m].
GF_HOST_DEVICE inline double horizontalDistance(double sx, double sy, double px, double py) {
  return sqrt(horizontalDistance2(sx, sy, px, py));
}

/// \brief Terrain grade of the sparse-tile floor's reach (floorReach()).
constexpr double kFloorGrade = 0.1;
/// \brief Share of its tile a floor beyond floor_max_shift must hold (floorShare()).
constexpr double kFloorFarShare = 0.8;

/// \brief How far a sparse tile's floor may lie off the cloud-wide plane [m]: `max_shift`
///        (floor_max_shift), or kFloorGrade times the horizontal distance from the sensor to
///        the tile's nearest point (`near2`, squared) where that is more. Only a tile whose lowest
///        point (`low_z`) lies below the sensor (`sensor_z`) reaches farther, and only in a scan
///        with a sensor (`has_sensor`): the ground a sensor sees lies below it, while far out a
///        lone scan line across a crown fills its tile. Terrain of a steady grade parts from a
///        plane fitted near the sensor in proportion to the distance: a 16-beam sensor 3-4 m up
///        sees ground only from 15-20 m on, 1-3 m over or under that plane
///        (docs/normal_method.md, "Sparse-tile floor far from the sensor"; grades 0.05-0.15 one
///        plateau).
GF_HOST_DEVICE inline double floorReach(double max_shift, bool has_sensor, double low_z,
                                        double sensor_z, double near2) {
  const bool under = has_sensor && low_z < sensor_z;
  return under ? fmax(max_shift, kFloorGrade * sqrt(near2)) : max_shift;
}

/// \brief The share of a sparse tile's points within plane_distance over its lowest level
///        (`low` off the cloud-wide plane) that makes that level its floor: `share`
///        (floor_share), and kFloorFarShare beyond `max_shift`: there the lowest of the few scan
///        lines across a wall or a car (a third to a half of its points) must not pass, open
///        ground seen from far fills nearly all of its tile (0.7-0.9 one plateau).
GF_HOST_DEVICE inline double floorShare(double share, double max_shift, double low) {
  return fabs(low) > max_shift ? fmax(share, kFloorFarShare) : share;
}

/// \brief The support distance of a RANSAC draw for planeAboveSensor(): the horizontal distance
///        from the sensor (sx, sy) to the nearest of the draw's three points a, b, c.
GF_HOST_DEVICE inline double drawReach(double sx, double sy, double ax, double ay, double bx,
                                       double by, double cx, double cy) {
  return fmin(fmin(horizontalDistance(sx, sy, ax, ay), horizontalDistance(sx, sy, bx, by)),
              horizontalDistance(sx, sy, cx, cy));
}

/// \brief Ground is seen from above: true when the plane n.q + d = 0 (unit normal n, offsets q
///        from the plane's origin) passes above the sensor, whose offset from that origin is
///        (sx, sy, sz), by more than 0.2 m + tan(1 deg) x `r` (tan(2 deg) for a `draw` of
///        three points, whose tilt is less certain), `r` the horizontal distance from the
///        sensor to the plane's support (of a draw, the nearest of its three points; of a
///        refit, its inliers' mean). A sensor sees a surface only from its free
///        side, and the free side of the ground is up: a horizontal plane the sensor lies under
///        is a ceiling, a table top or the underside of a deck, however large. The margin takes
///        a plane's tilt error times the distance it is carried to the sensor; the sensor's own
///        height above the ground adds to it (docs/normal_method.md, "Ceilings"). RANSAC skips
///        such a draw, and a refit that passes above the sensor fails the fit (CPU and GPU
///        alike, the same expressions in double).
GF_HOST_DEVICE inline bool planeAboveSensor(double nx, double ny, double nz, double d, double sx,
                                            double sy, double sz, double r, bool draw) {
  constexpr double kMargin = 0.2;                  // [m]
  constexpr double kFitSlope = 0.0175;             // tan(1 deg): a least-squares refit [m/m]
  constexpr double kDrawSlope = 0.035;             // tan(2 deg): a draw of three points [m/m]
  double h = (nx * sx + ny * sy) + (nz * sz + d);  // the sensor's signed distance along n
  if (nz < 0.0) h = -h;
  return h < -(kMargin + (draw ? kDrawSlope : kFitSlope) * r);
}

/// \brief Whether a refit is judged by planeAboveSensor(): its inliers span the plane both ways
///        (`ev1`, `ev2` the middle and largest eigenvalues of their covariance: the narrower
///        spread at least a seventh of the wider, ev1 >= 0.02 ev2). The inliers of a far tile
///        of a sparse sensor lie along one or two scan lines, and the fit does not measure the
///        tilt about their direction: such a plane is not judged (failing it sent the tile to
///        the cloud-wide plane: F1 -1 point on hills). 0.01-0.04 score alike within 0.1 on
///        the dev groups and the sensor sweep, 0.1 loses the garages (docs/normal_method.md,
///        "Ceilings").
GF_HOST_DEVICE inline bool refitJudged(double ev1, double ev2) { return ev1 >= 0.02 * ev2; }

/// \brief Whether planeAboveSensor() applies to a scan: at least a tenth of its voted points
///        within 10 m of the sensor (horizontally: `near` of them, nearSensor()) lie 0.3 m or
///        more below it (`below`, belowSensor()): the ground around a sensor lies under it. A
///        cloud in a frame whose origin is on the ground (base_footprint; the world frame of
///        merged stations or a map) has its sensor elsewhere, and there no plane is judged: the
///        KITTI frames moved to their road level hold 1-3 % of their near ground 0.3 m or more
///        below the origin, a parking level seen from 0.3 m over its floor passes
///        (docs/normal_method.md, "Ceilings").
GF_HOST_DEVICE inline bool sensorAboveGround(unsigned long long below, unsigned long long near) {
  return near > 0 && 10ULL * below >= near;
}

/// \brief The x/y columns of the overhead test (a scan with no sensor to judge planes by):
///        0.5 m cells over the bounding box, the side doubled until at most 4 Mi columns.
struct OverheadGrid {
  double min_x, min_y;   ///< corner of the box [m]
  double inv_cell;       ///< 1 / side [1/m]
  std::uint32_t nx, ny;  ///< columns along x and y
};

/// \brief The OverheadGrid of the box (min_x, min_y)-(max_x, max_y).
GF_HOST_DEVICE inline OverheadGrid overheadGrid(double min_x, double min_y, double max_x,
                                                double max_y) {
  double cell = 0.5;  // [m]: a 0.25-1 m column gives the same labels within 0.1 F1
  while (((max_x - min_x) / cell + 1.0) * ((max_y - min_y) / cell + 1.0) > 4194304.0) cell *= 2.0;
  OverheadGrid g;
  g.min_x = min_x;
  g.min_y = min_y;
  g.inv_cell = 1.0 / cell;
  g.nx = cellIndex(max_x, min_x, g.inv_cell) + 1;
  g.ny = cellIndex(max_y, min_y, g.inv_cell) + 1;
  return g;
}

/// \brief The column of (x, y) in `g` (row-major, x fastest).
GF_HOST_DEVICE inline std::size_t overheadColumn(const OverheadGrid& g, float x, float y) {
  const std::uint32_t cx = cellIndex(x, g.min_x, g.inv_cell);
  const std::uint32_t cy = cellIndex(y, g.min_y, g.inv_cell);
  return static_cast<std::size_t>(cy < g.ny ? cy : g.ny - 1) * g.nx + (cx < g.nx ? cx : g.nx - 1);
}

/// \brief Whether a voted point at height `z` lies over another surface: 1 m or more above the
///        lowest voted point `column_low` of its column. Ground is the lowest flat surface
///        there is; a flat surface with another one under it is a ceiling, a deck, a roof or a
///        table top. Applied where no sensor judges the planes (registered clouds, frames on
///        the ground), the voted points over others are left out of the plane stage. 1 m lies
///        above kerbs, steps and the z span of a 0.5 m column of ground that passes the angle
///        window, and below a storey; 0.5-2 m give the same labels within 0.1 F1
///        (docs/normal_method.md, "Ceilings").
GF_HOST_DEVICE inline bool overheadPoint(float z, float column_low) {
  return static_cast<double>(z) - static_cast<double>(column_low) >= 1.0;
}

/// \brief A voted point (dx, dy) from the sensor horizontally counts for sensorAboveGround().
GF_HOST_DEVICE inline bool nearSensor(double dx, double dy) { return dx * dx + dy * dy <= 100.0; }

/// \brief A near voted point at height `z` lies under the sensor (height `sz`).
GF_HOST_DEVICE inline bool belowSensor(float z, double sz) {
  return static_cast<double>(z) <= sz - 0.3;
}

/// \brief Least-squares plane z = a x + b y + c through the ground neighbours of one point, in
///        coordinates relative to that point (the local-ground stage, local_ground.h): the
///        neighbourhood sums of the PCA (szz unused). add() in the neighbour list's order on the
///        CPU and the GPU, so both round alike.
struct LocalGroundFit : NeighborhoodSums {
  /// \brief True when at least `min_count` points were added, they span an area (not one scan
  ///        line: the smaller spread of their x/y is at least kLocalGroundMinSpread of the larger),
  ///        the plane's normal is within the tilt `min_abs_nz` allows, and the point (the
  ///        origin) lies at most `below` under the plane or `above` over it (distances along
  ///        the plane's normal).
  GF_HOST_DEVICE bool accepts(int min_count, double below, double above, double min_abs_nz) const;
};

/// \brief The x/y spread of a local-ground neighbour set across its longest direction, at least
///        this share of the spread along it (det / trace^2 of the 2 x 2 covariance, which is
///        about the ratio of its eigenvalues when that is small). Far points' neighbours lie on
///        one or two scan lines, which fix no plane across them.
constexpr double kLocalGroundMinSpread = 0.01;

GF_HOST_DEVICE inline bool LocalGroundFit::accepts(int min_count, double below, double above,
                                                   double min_abs_nz) const {
  if (m < min_count || m < 3) return false;
  const double inv = 1.0 / static_cast<double>(m);
  const double mx = sx * inv, my = sy * inv, mz = sz * inv;
  const double cxx = sxx - sx * mx, cxy = sxy - sx * my, cyy = syy - sy * my;
  const double cxz = sxz - sx * mz, cyz = syz - sy * mz;
  const double det = cxx * cyy - cxy * cxy;
  const double tr = cxx + cyy;
  if (!(det > kLocalGroundMinSpread * tr * tr)) return false;
  const double a = (cxz * cyy - cyz * cxy) / det;
  const double b = (cyz * cxx - cxz * cxy) / det;
  const double c = mz - a * mx - b * my;  // the plane's z at the point's x/y, minus its z
  const double g2 = 1.0 + a * a + b * b;  // 1 / n_z^2
  if (min_abs_nz * min_abs_nz * g2 > 1.0) return false;
  const double band = c >= 0.0 ? below : above;  // c > 0: the point is under the plane
  return c * c <= band * band * g2;              // (c n_z)^2 <= band^2
}

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_CPU_GPU_COMMON_H
