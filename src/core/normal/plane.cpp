// Stage 5 of the normal filter: RANSAC plane(s) through the voted points and the distance test.

#include "plane.h"

#include <omp.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "common/radix_sort.h"
#include "cpu_gpu_common.h"
#include "normal/cell_keys.h"

namespace ground_filter {
namespace normal {

namespace {

double distanceOf(const Plane& plane, const float* p) { return plane.distance(p[0], p[1], p[2]); }

// A plane's normal and origin as the arrays of the CPU/GPU helpers (planeZAt()).
void planeArrays(const Plane& plane, double n[3], double o[3]) {
  for (int c = 0; c < 3; ++c) {
    n[c] = plane.normal[c];
    o[c] = plane.origin[c];
  }
}

/// Sums the W values term(j, v) writes for the list positions j in [0, m) where it returns true,
/// in the GPU's order (ground_planes.cu): kPlaneSumLanes interleaved lanes, then the lanes in
/// order; returns how many were added. A lane starts at +0.0 and so never becomes -0.0: the
/// GPU's lanes that hold no point add nothing.
template <int W, class Term>
std::size_t sumInliers(std::size_t m, Term term, double out[W]) {
  std::fill_n(out, W, 0.0);
  std::size_t count = 0;
  const std::size_t lanes = std::min<std::size_t>(m, kPlaneSumLanes);
  double lane[kPlaneSumLanes][W];
  for (std::size_t l = 0; l < lanes; ++l) std::fill_n(lane[l], W, 0.0);
  for (std::size_t j = 0; j < m; ++j) {
    double v[W];
    if (!term(j, v)) continue;
    for (int w = 0; w < W; ++w) lane[j % kPlaneSumLanes][w] += v[w];
    ++count;
  }
  for (std::size_t l = 0; l < lanes; ++l) {
    for (int w = 0; w < W; ++w) out[w] += lane[l][w];
  }
  return count;
}

// planeAboveSensor() of the plane n.q + d = 0 (offsets q from `o`) drawn through the points
// a, b, c (offsets from `o`). Out of line, as refitAboveSensor(): the RANSAC loop around it stays
// as compact as without a sensor.
[[gnu::noinline]] bool drawAboveSensor(const double* sensor, const Eigen::Vector3d& o,
                                       const Eigen::Vector3d& n, double d, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const double sx = sensor[0] - o.x(), sy = sensor[1] - o.y(), sz = sensor[2] - o.z();
  const double r = drawReach(sx, sy, a.x(), a.y(), b.x(), b.y(), c.x(), c.y());
  return planeAboveSensor(n.x(), n.y(), n.z(), d, sx, sy, sz, r, true);
}

// planeAboveSensor() of a refitted plane n.q + d = 0 whose inliers' mean is `mean` (offsets
// from `o`).
[[gnu::noinline]] bool refitAboveSensor(const double* sensor, const Eigen::Vector3d& o,
                                        const Eigen::Vector3d& n, double d,
                                        const Eigen::Vector3d& mean) {
  const double sx = sensor[0] - o.x(), sy = sensor[1] - o.y(), sz = sensor[2] - o.z();
  const double r = horizontalDistance(sx, sy, mean.x(), mean.y());
  return planeAboveSensor(n.x(), n.y(), n.z(), d, sx, sy, sz, r, false);
}

}  // namespace

bool fitPlaneRansac(const float* xyz, const std::vector<std::uint32_t>& idx, int iterations,
                    double threshold, double max_tilt_cos, std::uint64_t seed,
                    std::vector<std::uint32_t>* eval_scratch, Plane* plane, const double* sensor) {
  Plane best;
  const std::size_t m = idx.size();
  if (m < 3) return false;
  const float* o = xyz + 3 * static_cast<std::size_t>(idx[0]);
  best.origin = Eigen::Vector3d(o[0], o[1], o[2]);
  auto point = [&](std::uint32_t i) {
    const float* p = xyz + 3 * static_cast<std::size_t>(i);
    return Eigen::Vector3d(p[0] - best.origin.x(), p[1] - best.origin.y(), p[2] - best.origin.z());
  };
  // Score on an evenly strided subset of large sets (deterministic, keeps big tiles cheap).
  std::vector<std::uint32_t>& eval = *eval_scratch;
  eval.clear();
  const std::size_t stride = (m + kRansacEvalPoints - 1) / kRansacEvalPoints;
  for (std::size_t i = 0; i < m; i += stride) eval.push_back(idx[i]);

  SplitMix64 rng(seed);
  std::size_t best_count = 0;
  Eigen::Vector3d best_n = Eigen::Vector3d::UnitZ();
  double best_d = 0.0;
  double needed = iterations;
  for (int it = 0; it < iterations && it < needed; ++it) {
    const std::size_t a = rng.below(m), b = rng.below(m), c = rng.below(m);
    if (a == b || a == c || b == c) continue;
    const Eigen::Vector3d pa = point(idx[a]);
    Eigen::Vector3d nrm = (point(idx[b]) - pa).cross(point(idx[c]) - pa);
    const double len = nrm.norm();
    if (!(len > 1e-9)) continue;  // collinear or duplicate sample
    nrm /= len;
    if (std::abs(nrm.z()) < max_tilt_cos) continue;
    const double d = -nrm.dot(pa);
    if (sensor && drawAboveSensor(sensor, best.origin, nrm, d, pa, point(idx[b]), point(idx[c]))) {
      continue;  // a plane over the sensor: a ceiling, not the ground
    }
    std::size_t count = 0;
    for (std::uint32_t i : eval) {
      if (std::abs(nrm.dot(point(i)) + d) <= threshold) ++count;
    }
    if (count > best_count) {
      best_count = count;
      best_n = nrm;
      best_d = d;
      // Adaptive stop: enough hypotheses for 99 % confidence at this inlier ratio.
      const double w = static_cast<double>(count) / static_cast<double>(eval.size());
      const double fail = 1.0 - w * w * w;
      needed = fail <= 0.0 ? 0.0 : std::ceil(std::log(0.01) / std::log(fail));
    }
  }
  if (best_count < 3) return false;

  // Least-squares refinement on all inliers (centred covariance, smallest eigenvector), summed in
  // the GPU's order (sumInliers()), so both round alike.
  auto inlier = [&](const Eigen::Vector3d& p) {
    return std::abs(best_n.dot(p) + best_d) <= threshold;
  };
  double mean_sum[3];
  const std::size_t inliers = sumInliers<3>(
      m,
      [&](std::size_t j, double* v) {
        const Eigen::Vector3d p = point(idx[j]);
        v[0] = p.x();
        v[1] = p.y();
        v[2] = p.z();
        return inlier(p);
      },
      mean_sum);
  best.normal = best_n;
  best.d = best_d;
  *plane = best;
  if (inliers < 3) return true;
  const Eigen::Vector3d mean =
      Eigen::Vector3d(mean_sum[0], mean_sum[1], mean_sum[2]) / static_cast<double>(inliers);
  double c[6];  // xx xy xz yy yz zz
  sumInliers<6>(
      m,
      [&](std::size_t j, double* v) {
        const Eigen::Vector3d p = point(idx[j]);
        const Eigen::Vector3d q = p - mean;
        v[0] = q.x() * q.x();
        v[1] = q.x() * q.y();
        v[2] = q.x() * q.z();
        v[3] = q.y() * q.y();
        v[4] = q.y() * q.z();
        v[5] = q.z() * q.z();
        return inlier(p);
      },
      c);
  Eigen::Matrix3d cov;
  cov << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  Eigen::Vector3d n = es.eigenvectors().col(0);
  if (n.dot(best_n) < 0.0) n = -n;
  if (std::isfinite(n.x()) && std::abs(n.z()) >= max_tilt_cos) {
    if (sensor && refitJudged(es.eigenvalues()(1), es.eigenvalues()(2)) &&
        refitAboveSensor(sensor, best.origin, n, -n.dot(mean), mean)) {
      return false;  // the refit passes over the sensor
    }
    plane->normal = n;
    plane->d = -n.dot(mean);
  }
  return true;
}

void PlaneStage::sortIntoTiles(const std::vector<float>& xyz, std::size_t n, const Extent& extent,
                               const NormalGroundFilterParams& p, int threads) {
  keys_.resize(n);
  if (p.local_planes) {
    const double tile = std::max(p.tile_size, extent.size() / 4.0e9);
    tile_size_ = tile;
    tile_min_x_ = extent.min_x;
    tile_min_y_ = extent.min_y;
    // Keys tx << y_bits_ | ty: the order of (tx << 32) | ty (tileKey(), the RANSAC seeds) in
    // the fewest radix passes (a KITTI frame: 12 bits, one pass instead of three).
    y_bits_ = radixBitsFor(cellIndex(extent.max_y, extent.min_y, 1.0 / tile));
    const int nt = static_cast<int>(std::min<std::size_t>(threads, n / 16384 + 1));
#pragma omp parallel num_threads(nt)
    {
      const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
      const std::size_t parts = static_cast<std::size_t>(omp_get_num_threads());
      tileKeysOf(xyz.data(), n * t / parts, n * (t + 1) / parts, extent.min_x, extent.min_y,
                 1.0 / tile, y_bits_, keys_.data());
    }
  } else {
    y_bits_ = 0;
    std::fill(keys_.begin(), keys_.end(), 0);
  }
  radixSortByKey(keys_, &tile_order_, &sort_scratch_, threads);
  tiles_.clear();
  const std::vector<std::uint64_t>& sorted = sort_scratch_.keys;  // keys_ in tile_order_
  for (std::size_t b = 0; b < n;) {
    std::size_t e = b + 1;
    while (e < n && sorted[e] == sorted[b]) ++e;
    tiles_.emplace_back(b, e);
    b = e;
  }
}

bool PlaneStage::needGlobalPlane(const std::vector<std::uint8_t>& voted,
                                 const NormalGroundFilterParams& p) const {
  if (!p.local_planes) return true;
  for (const auto& tl : tiles_) {
    std::size_t count = 0;
    for (std::size_t j = tl.first; j < tl.second && count < kMinTilePoints; ++j) {
      count += voted[tile_order_[j]];
    }
    if (count < kMinTilePoints) return true;
  }
  return false;
}

bool PlaneStage::fitGlobalPlane(const std::vector<float>& xyz,
                                const std::vector<std::uint8_t>& voted,
                                const NormalGroundFilterParams& p, double min_abs_nz,
                                std::uint64_t base_seed, const double* sensor, Plane* global) {
  std::vector<std::uint32_t>& all_voted = global_idx_;
  all_voted.clear();
  all_voted.reserve(voted.size());
  for (std::size_t i = 0; i < voted.size(); ++i) {
    if (voted[i]) all_voted.push_back(static_cast<std::uint32_t>(i));
  }
  return fitPlaneRansac(xyz.data(), all_voted, p.ransac_iterations, p.plane_distance, min_abs_nz,
                        base_seed, &global_eval_, global, sensor);
}

void PlaneStage::lowerToFloor(const std::vector<float>& xyz, std::size_t tb, std::size_t te,
                              const NormalGroundFilterParams& p, const double* sensor,
                              Plane* plane) const {
  // Sparse tile on the cloud-wide plane (the near road dominates it): far terrain that rises
  // or falls beside the road is off it. When enough of the tile lies on its lowest level,
  // that level is its ground (docs/normal_method.md, "Sparse-tile floor"); the farther from
  // the sensor, the farther off the plane it may lie (floorReach()).
  const double up = plane->normal.z() < 0.0 ? -1.0 : 1.0;
  double low = std::numeric_limits<double>::infinity();
  double near2 = sensor ? std::numeric_limits<double>::infinity() : 0.0;
  float low_z = std::numeric_limits<float>::infinity();
  for (std::size_t j = tb; j < te; ++j) {
    const float* q = &xyz[3 * std::size_t{tile_order_[j]}];
    low = std::min(low, up * distanceOf(*plane, q));
    low_z = std::min(low_z, q[2]);
    if (sensor) near2 = std::min(near2, horizontalDistance2(sensor[0], sensor[1], q[0], q[1]));
  }
  const double reach =
      floorReach(p.floor_max_shift, sensor != nullptr, low_z, sensor ? sensor[2] : 0.0, near2);
  if (low >= -reach && low <= reach) {
    std::size_t on_floor = 0;
    for (std::size_t j = tb; j < te; ++j) {
      const double h = up * distanceOf(*plane, &xyz[3 * std::size_t{tile_order_[j]}]);
      on_floor += h >= low && h <= low + p.plane_distance;
    }
    const double share = floorShare(p.floor_share, p.floor_max_shift, low);
    if (static_cast<double>(on_floor) >= share * static_cast<double>(te - tb)) {
      plane->d -= up * low;
    }
  }
}

void PlaneStage::distanceBand(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                              std::size_t t, const Plane& plane, const NormalGroundFilterParams& p,
                              double* lo, double* hi) const {
  // Band of the voted points' signed distances within the threshold (in tile order, as the
  // GPU's vlist).
  *lo = -p.plane_distance;
  *hi = p.plane_distance;
  if (!p.std_filter) return;
  double s = 0.0, s2 = 0.0;
  std::size_t c = 0;
  for (std::size_t j = tiles_[t].first; j < tiles_[t].second; ++j) {
    const std::uint32_t i = tile_order_[j];
    if (!voted[i]) continue;
    const double d = distanceOf(plane, &xyz[3 * static_cast<std::size_t>(i)]);
    if (std::abs(d) <= p.plane_distance) {
      s += d;
      s2 += d * d;
      ++c;
    }
  }
  if (c > 0) {
    const double mean = s / c;
    const double sd = std::sqrt(std::max(0.0, s2 / c - mean * mean));
    *lo = std::max(*lo, mean - p.std_multiplier * sd);
    *hi = std::min(*hi, mean + p.std_multiplier * sd);
  }
}

void PlaneStage::run(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                     const Extent& extent, const NormalGroundFilterParams& p, double min_abs_nz,
                     int threads, std::vector<std::uint8_t>* ground_out,
                     std::vector<float>* heights, const double* sensor) {
  const std::size_t n = voted.size();
  std::vector<std::uint8_t>& ground = *ground_out;
  ground.assign(n, 0);
  if (heights) heights->assign(n, std::numeric_limits<float>::quiet_NaN());
  sortIntoTiles(xyz, n, extent, p, threads);
  const double* floor_from = sensor;  // the floor's reach grows from the sensor in any case
  if (sensor) {  // the check applies only where the origin lies above the voted points
    std::uint64_t below = 0, near = 0;
    const int ct = static_cast<int>(std::min<std::size_t>(std::max(threads, 1), n / 32768 + 1));
#pragma omp parallel for num_threads(ct) schedule(static) reduction(+ : below, near)
    for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(n); ++ii) {
      const std::size_t i = static_cast<std::size_t>(ii);
      if (!voted[i] || !nearSensor(xyz[3 * i] - sensor[0], xyz[3 * i + 1] - sensor[1])) continue;
      ++near;
      below += belowSensor(xyz[3 * i + 2], sensor[2]);
    }
    if (!sensorAboveGround(below, near)) sensor = nullptr;
  }
  if (!sensor) {  // no sensor to judge planes by: no voted point over another (overheadPoint())
    unroofed_.assign(voted.begin(), voted.end());
    unvoteOverhead(xyz, extent, &unroofed_);
    runTiles(xyz, unroofed_, p, min_abs_nz, threads, ground_out, heights, nullptr, floor_from);
    return;
  }
  runTiles(xyz, voted, p, min_abs_nz, threads, ground_out, heights, sensor, floor_from);
}

void PlaneStage::unvoteOverhead(const std::vector<float>& xyz, const Extent& extent,
                                std::vector<std::uint8_t>* voted) {
  const OverheadGrid g = overheadGrid(extent.min_x, extent.min_y, extent.max_x, extent.max_y);
  column_low_.assign(static_cast<std::size_t>(g.nx) * g.ny, std::numeric_limits<float>::max());
  std::vector<std::uint8_t>& v = *voted;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!v[i]) continue;
    float& low = column_low_[overheadColumn(g, xyz[3 * i], xyz[3 * i + 1])];
    low = std::min(low, xyz[3 * i + 2]);
  }
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (v[i] &&
        overheadPoint(xyz[3 * i + 2], column_low_[overheadColumn(g, xyz[3 * i], xyz[3 * i + 1])])) {
      v[i] = 0;
    }
  }
}

void PlaneStage::runTiles(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                          const NormalGroundFilterParams& p, double min_abs_nz, int threads,
                          std::vector<std::uint8_t>* ground_out, std::vector<float>* heights,
                          const double* sensor, const double* floor_from) {
  // Each thread's lists hold any tile (dynamic schedule: which thread gets which tile varies),
  // so a scan with the same tiles allocates nothing.
  std::size_t longest_tile = 0;
  for (const auto& tl : tiles_) longest_tile = std::max(longest_tile, tl.second - tl.first);
  thread_idx_.resize(threads);
  thread_eval_.resize(threads);
  for (int t = 0; t < threads; ++t) {
    thread_idx_[t].reserve(longest_tile);
    thread_eval_[t].reserve(kRansacEvalPoints);
  }

  // Cloud-wide plane: the only one without local planes, the fallback for sparse tiles and,
  // with a sensor, for the tiles whose own fit finds no plane below it (then fitted after the
  // tiles, only where one needs it: the same plane as fitted before them).
  const std::uint64_t base_seed = ransacBaseSeed(static_cast<std::uint32_t>(p.ransac_seed));
  Plane global;
  bool global_valid = false;
  const bool global_fitted = needGlobalPlane(voted, p);
  deferred_.assign(tiles_.size(), 0);
  wants_global_.assign(tiles_.size(), 0);
  tile_plane_.resize(tiles_.size());
  tile_kind_.assign(tiles_.size(), kNoPlane);
  tile_voted_.resize(tiles_.size());

  // Each tile's plane: its own fit, else the cloud-wide plane, which one thread fits beside the
  // tiles' fits where some tile will need it (its own scratch; the same plane as fitted first).
  const int nt =
      static_cast<int>(std::min<std::size_t>(threads, tiles_.size() + (global_fitted ? 1 : 0)));
#pragma omp parallel num_threads(nt)
  {
#pragma omp single nowait
    if (global_fitted) {
      global_valid = fitGlobalPlane(xyz, voted, p, min_abs_nz, base_seed, sensor, &global);
    }
#pragma omp for schedule(dynamic, 1) nowait
    for (std::int64_t t = 0; t < static_cast<std::int64_t>(tiles_.size()); ++t) {
      std::vector<std::uint32_t>& tv = thread_idx_[omp_get_thread_num()];
      votedOfTile(voted, t, &tv);
      tile_voted_[t] = static_cast<std::uint32_t>(tv.size());
      if (p.local_planes && tv.size() >= kMinTilePoints) {
        const std::uint64_t seed =
            base_seed ^ (tileKey(sort_scratch_.keys[tiles_[t].first]) * 0x9e3779b97f4a7c15ULL);
        if (fitPlaneRansac(xyz.data(), tv, p.ransac_iterations, p.plane_distance, min_abs_nz, seed,
                           &thread_eval_[omp_get_thread_num()], &tile_plane_[t], sensor)) {
          tile_kind_[t] = kOwnPlane;
          continue;
        }
        if (sensor && !global_fitted) {
          deferred_[t] = 1;  // the cloud-wide plane, fitted below
          continue;
        }
      }
      wants_global_[t] = 1;
    }
  }  // (the region's end waits for the cloud-wide fit)
  for (std::size_t t = 0; t < tiles_.size(); ++t) {
    if (!wants_global_[t] || !global_valid) continue;
    tile_plane_[t] = global;
    tile_kind_[t] = kCloudPlane;
  }
  if (std::find(deferred_.begin(), deferred_.end(), 1) != deferred_.end() &&
      fitGlobalPlane(xyz, voted, p, min_abs_nz, base_seed, sensor, &global)) {
    for (std::size_t t = 0; t < tiles_.size(); ++t) {
      if (!deferred_[t]) continue;
      tile_plane_[t] = global;
      tile_kind_[t] = kCloudPlane;
    }
  }
  raised_.assign(tiles_.size(), -1);
  if (p.local_planes) raisedTiles();
#pragma omp parallel for num_threads(nt) schedule(dynamic, 1)
  for (std::int64_t t = 0; t < static_cast<std::int64_t>(tiles_.size()); ++t) {
    if (tile_kind_[t] == kNoPlane) continue;
    // The distance test against its plane (a raised tile's: its donor's, as fitted).
    const Plane& plane = tile_plane_[raised_[t] >= 0 ? raised_[t] : t];
    labelTile(xyz, voted, t, plane, p, floor_from, ground_out, heights);
  }
}

void PlaneStage::raisedTiles() {
  // The planes stay as fitted: raised_ names each raised tile's donor (as the GPU's donor[]).
  const std::size_t nt = tiles_.size();
  const std::uint64_t y_max = (std::uint64_t{1} << y_bits_) - 1;
  // tiles_ are in key order (sortIntoTiles()).
  auto key_at = [&](std::uint64_t i) { return sort_scratch_.keys[tiles_[i].first]; };
  for (std::size_t t = 0; t < nt; ++t) {
    if (tile_kind_[t] != kOwnPlane) continue;
    const std::uint64_t key = sort_scratch_.keys[tiles_[t].first];
    const std::uint64_t tx = key >> y_bits_, ty = key & y_max;
    double o[3], n[3];
    planeArrays(tile_plane_[t], n, o);
    const double cx = tile_min_x_ + (static_cast<double>(tx) + 0.5) * tile_size_;
    const double cy = tile_min_y_ + (static_cast<double>(ty) + 0.5) * tile_size_;
    const double zt = planeZAt(n, tile_plane_[t].d, o, cx, cy);
    double zs[8];
    std::int64_t who[8];
    int k = 0;
    for (int v = 0; v < 8; ++v) {
      std::uint64_t want;
      if (!tileNeighbourKey(tx, ty, y_bits_, v, &want)) continue;
      const std::int64_t u = findTile(key_at, nt, want);
      if (u < 0 || tile_kind_[u] != kOwnPlane) continue;
      planeArrays(tile_plane_[u], n, o);
      zs[k] = planeZAt(n, tile_plane_[u].d, o, cx, cy);
      who[k++] = u;
    }
    const int mid = raisedTileMedian(zt, zs, k);
    if (mid >= 0) raised_[t] = who[mid];
  }
}

void PlaneStage::votedOfTile(const std::vector<std::uint8_t>& voted, std::size_t t,
                             std::vector<std::uint32_t>* tv) const {
  tv->clear();
  for (std::size_t j = tiles_[t].first; j < tiles_[t].second; ++j) {
    if (voted[tile_order_[j]]) tv->push_back(tile_order_[j]);
  }
}

void PlaneStage::labelTile(const std::vector<float>& xyz, const std::vector<std::uint8_t>& voted,
                           std::size_t t, Plane plane, const NormalGroundFilterParams& p,
                           const double* floor_from, std::vector<std::uint8_t>* ground,
                           std::vector<float>* heights) const {
  const std::size_t tb = tiles_[t].first, te = tiles_[t].second;
  if (p.local_planes && tile_voted_[t] < kMinTilePoints && p.floor_share > 0.0) {
    lowerToFloor(xyz, tb, te, p, floor_from, &plane);
  }
  double lo, hi;
  distanceBand(xyz, voted, t, plane, p, &lo, &hi);
  if (heights) {  // for the vegetation stage: up = the side the plane's normal z points to
    const double up = plane.normal.z() < 0.0 ? -1.0 : 1.0;
    for (std::size_t j = tb; j < te; ++j) {
      const std::uint32_t i = tile_order_[j];
      (*heights)[i] = static_cast<float>(up * distanceOf(plane, &xyz[3 * std::size_t{i}]));
    }
  }
  for (std::size_t j = tb; j < te; ++j) {
    const std::uint32_t i = tile_order_[j];
    if (!voted[i] && !p.plane_all_points) continue;
    const double d = distanceOf(plane, &xyz[3 * static_cast<std::size_t>(i)]);
    (*ground)[i] = d >= lo && d <= hi;
  }
}

}  // namespace normal
}  // namespace ground_filter
