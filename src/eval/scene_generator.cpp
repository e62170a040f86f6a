#include "eval/scene_generator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "eval/scene_terrain.h"
#include "eval/scene_world.h"
#include "ground_filter/param_parse.h"

namespace ground_filter {
namespace scene {

namespace {

// The scan pattern: columns of rays sharing an azimuth, rows of elevations.
struct Pattern {
  std::vector<double> azimuth;    // per column [rad]
  std::vector<double> elevation;  // per row [rad]
  // Non-empty: one ray per column at this elevation [rad] instead of the rows (kRosette).
  std::vector<double> column_elevation;
  double max_range = 0.0;
};

Pattern lidarPattern(const SceneParams& p) {
  Pattern pat;
  pat.max_range = p.lidar_max_range;
  pat.azimuth.resize(static_cast<std::size_t>(p.azimuth_steps));
  for (int c = 0; c < p.azimuth_steps; ++c) pat.azimuth[c] = 2.0 * kPi * c / p.azimuth_steps;
  // Like the HDL-64E, the upper half of the lasers covers the top 10.33 of 26.8 deg (denser near
  // the horizon), the lower half the rest.
  const double span = p.vertical_max_deg - p.vertical_min_deg;
  const double split = p.vertical_max_deg - span * (10.33 / 26.8);
  const int upper = p.beams / 2;
  for (int b = 0; b < p.beams; ++b) {
    double deg;
    if (p.beams == 1) {
      deg = p.vertical_min_deg;
    } else if (p.uniform_beams) {
      deg = p.vertical_max_deg - span * b / (p.beams - 1);
    } else if (b < upper) {
      deg = p.vertical_max_deg - (p.vertical_max_deg - split) * b / std::max(upper, 1);
    } else {
      const int lower = p.beams - upper;
      deg = split - (split - p.vertical_min_deg) * (b - upper + 1) / lower;
    }
    pat.elevation.push_back(deg * kDegToRad);
  }
  return pat;
}

// Uniform angular grid of about `rays` rays over 360 deg x the TLS elevation span.
// Two prisms turning against each other at incommensurate rates (as Livox's Risley prisms): the
// deflection is the sum of two circles of a quarter of the field each, so the rays fill a disc
// of the field's radius in petals that never repeat; densest at the centre and the rim.
Pattern rosettePattern(const SceneParams& p) {
  Pattern pat;
  pat.max_range = p.lidar_max_range;
  const std::size_t n = p.rosette_rays;
  const double a = 0.25 * p.rosette_fov_deg * kDegToRad, pitch = p.rosette_pitch_deg * kDegToRad;
  const double turns = 40.0, ratio = -0.6180339887;  // prism 2 turns -1/phi as fast
  pat.azimuth.resize(n);
  pat.column_elevation.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = 2.0 * kPi * turns * static_cast<double>(i) / static_cast<double>(n);
    const double dx = a * (std::cos(t) + std::cos(ratio * t));
    const double dy = a * (std::sin(t) + std::sin(ratio * t));
    pat.azimuth[i] = dx < 0.0 ? dx + 2.0 * kPi : dx;  // castPattern wants [0, 2 pi)
    pat.column_elevation[i] = dy + pitch;
  }
  return pat;
}

Pattern tlsPattern(const SceneParams& p, double rays) {
  Pattern pat;
  pat.max_range = p.tls_max_range;
  const double span = p.tls_max_elevation_deg - p.tls_min_elevation_deg;
  const double step = std::sqrt(360.0 * span / std::max(rays, 1.0));
  const int cols = std::max(8, static_cast<int>(std::lround(360.0 / step)));
  const int rows = std::max(2, static_cast<int>(std::lround(span / step)) + 1);
  pat.azimuth.resize(cols);
  for (int c = 0; c < cols; ++c) pat.azimuth[c] = 2.0 * kPi * c / cols;
  pat.elevation.resize(rows);
  for (int r = 0; r < rows; ++r) {
    pat.elevation[r] = (p.tls_min_elevation_deg + span * r / (rows - 1)) * kDegToRad;
  }
  return pat;
}

// Per-block output so that blocks can be cast in parallel and joined in scan order.
struct Block {
  std::vector<float> xyz, intensity;
  std::vector<std::uint16_t> ring;
  std::vector<std::uint8_t> truth;
  std::vector<std::uint16_t> semantic;
};

constexpr std::size_t kBlocks = 256;

// The noise of the returns of one block of columns: an explicitly seeded engine and the
// distributions drawing from it.
struct PointNoise {
  PointNoise(std::seed_seq& seq, double sigma) : rng(seq), range(0.0, sigma > 0.0 ? sigma : 1.0) {}
  std::mt19937 rng;
  std::normal_distribution<double> range;
  std::normal_distribution<float> intensity{0.0f, 0.03f};
  std::uniform_real_distribution<double> rough{-1.0, 1.0};
};

// Least range between two echoes of one beam that a dual-return sensor separates [m].
constexpr double kEchoSeparation = 1.0;

// A uniform number in [0, 1) from the scene's seeds and a ray (column c, row r): the same ray
// decides the same in every pass (the TLS sizing pass draws no noise).
double unitHash(std::uint32_t seed, std::uint32_t noise_seed, std::size_t c, std::size_t r) {
  std::uint64_t x = (static_cast<std::uint64_t>(seed) << 32 | noise_seed) ^
                    (static_cast<std::uint64_t>(c) * 0x9E3779B97F4A7C15ull) ^
                    (static_cast<std::uint64_t>(r) * 0xC2B2AE3D27D4EB4Full);
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBull;
  x ^= x >> 31;
  return static_cast<double>(x >> 11) * 0x1.0p-53;
}

GeneratedScan castPattern(const SceneParams& p, const Scene& scene, const Pattern& pat,
                          bool with_noise) {
  const bool own = !pat.column_elevation.empty();  // one ray per column
  const std::size_t cols = pat.azimuth.size(), rows = own ? 1 : pat.elevation.size();
  const std::size_t blocks = std::min(kBlocks, cols);
  std::vector<Block> out(blocks);
  std::vector<double> cos_el(rows), sin_el(rows);
  for (std::size_t r = 0; r < rows && !own; ++r) {
    cos_el[r] = std::cos(pat.elevation[r]);
    sin_el[r] = std::sin(pat.elevation[r]);
  }
  const double sigma = p.range_noise_sigma;

#pragma omp parallel for schedule(dynamic, 1)
  for (long bi = 0; bi < static_cast<long>(blocks); ++bi) {
    const std::size_t b = static_cast<std::size_t>(bi);
    // One explicitly seeded engine per block: the result does not depend on the thread count.
    std::seed_seq seq{p.seed, p.noise_seed, static_cast<std::uint32_t>(b),
                      static_cast<std::uint32_t>(p.mode)};
    PointNoise first(seq, sigma);
    // Second echoes draw from their own engine: the first echoes are those of the scan without.
    std::seed_seq echo_seq{p.seed, p.noise_seed, static_cast<std::uint32_t>(b), 0x2ec0u};
    PointNoise second(echo_seq, sigma);
    std::vector<const SectorEntry*> objects;
    Block& blk = out[b];
    const std::size_t c0 = cols * b / blocks, c1 = cols * (b + 1) / blocks;
    blk.truth.reserve((c1 - c0) * rows);
    blk.xyz.reserve((c1 - c0) * rows * 3);
    blk.intensity.reserve((c1 - c0) * rows);
    blk.ring.reserve((c1 - c0) * rows);
    for (std::size_t c = c0; c < c1; ++c) {
      const double az = pat.azimuth[c];
      const double ca = std::cos(az), sa = std::sin(az);
      const double az_wrapped = az > kPi ? az - 2.0 * kPi : az;
      scene.candidates(az_wrapped, &objects);
      for (std::size_t r = 0; r < rows; ++r) {
        const double ce = own ? std::cos(pat.column_elevation[c]) : cos_el[r];
        const double se = own ? std::sin(pat.column_elevation[c]) : sin_el[r];
        const Vec3 d{ce * ca, ce * sa, se};
        const Hit hit = scene.cast(d, objects, p.min_range, pat.max_range);
        if (hit.t == kNoHit) continue;
        const auto emit = [&](const Hit& h, PointNoise& nz) {
          blk.truth.push_back(h.ground ? 1 : 0);
          if (!with_noise) return;
          const double range = sigma > 0.0 ? h.t + nz.range(nz.rng) : h.t;
          // Grass and dirt: the return comes from a blade or clod up to `roughness` off the
          // surface.
          const double dz = h.roughness > 0.f ? h.roughness * nz.rough(nz.rng) : 0.0;
          blk.xyz.push_back(static_cast<float>(d.x * range));
          blk.xyz.push_back(static_cast<float>(d.y * range));
          blk.xyz.push_back(static_cast<float>(d.z * range + dz));
          blk.semantic.push_back(h.cls);
          blk.intensity.push_back(std::clamp(h.reflectivity + nz.intensity(nz.rng), 0.0f, 1.0f));
          blk.ring.push_back(static_cast<std::uint16_t>(r));
        };
        emit(hit, first);
        // Dual-return sensor: part of the beam passes through foliage and the last echo comes
        // from the next surface behind it, right after the first in the scan's order.
        if (p.second_returns > 0.0 && hit.cls == kClassVegetation &&
            unitHash(p.seed, p.noise_seed, c, r) < p.second_returns) {
          const Hit last = scene.cast(d, objects, hit.t + kEchoSeparation, pat.max_range);
          if (last.t != kNoHit) emit(last, second);
        }
      }
    }
  }

  GeneratedScan scan;
  std::size_t n = 0;
  for (const Block& b : out) n += b.truth.size();
  scan.truth.reserve(n);
  if (with_noise) {
    scan.xyz.reserve(3 * n);
    scan.intensity.reserve(n);
    scan.ring.reserve(n);
    scan.semantic.reserve(n);
  }
  for (const Block& b : out) {
    scan.xyz.insert(scan.xyz.end(), b.xyz.begin(), b.xyz.end());
    scan.intensity.insert(scan.intensity.end(), b.intensity.begin(), b.intensity.end());
    scan.ring.insert(scan.ring.end(), b.ring.begin(), b.ring.end());
    scan.truth.insert(scan.truth.end(), b.truth.begin(), b.truth.end());
    scan.semantic.insert(scan.semantic.end(), b.semantic.begin(), b.semantic.end());
  }
  return scan;
}

// Keeps `keep` of the points, spread evenly over the scan (no sector is cut off).
void thinTo(GeneratedScan* scan, std::size_t keep) {
  const std::size_t n = scan->size();
  if (keep >= n) return;
  std::size_t w = 0;
  for (std::size_t i = 0; i < n; ++i) {
    // Point i is kept when floor((i+1) keep / n) steps up.
    if ((i + 1) * keep / n == i * keep / n) continue;
    for (int k = 0; k < 3; ++k) scan->xyz[3 * w + k] = scan->xyz[3 * i + k];
    scan->intensity[w] = scan->intensity[i];
    scan->ring[w] = scan->ring[i];
    scan->truth[w] = scan->truth[i];
    scan->semantic[w] = scan->semantic[i];
    ++w;
  }
  scan->xyz.resize(3 * w);
  scan->intensity.resize(w);
  scan->ring.resize(w);
  scan->truth.resize(w);
  scan->semantic.resize(w);
}

// Inserts `count` NaN points (non-ground, ring 0) evenly among the points.
void insertNans(GeneratedScan* scan, std::size_t count) {
  if (count == 0) return;
  const std::size_t n = scan->size(), total = n + count;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  GeneratedScan out;
  out.xyz.reserve(3 * total);
  out.intensity.reserve(total);
  out.ring.reserve(total);
  out.truth.reserve(total);
  out.semantic.reserve(total);
  std::size_t next_nan = 0, src = 0;
  for (std::size_t i = 0; i < total; ++i) {
    // NaN k sits at position (k + 1) * total / (count + 1) - 1.
    const bool is_nan = next_nan < count && i + 1 == (next_nan + 1) * total / (count + 1);
    if (is_nan || src >= n) {
      out.xyz.insert(out.xyz.end(), {nan, nan, nan});
      out.intensity.push_back(0.f);
      out.ring.push_back(0);
      out.truth.push_back(0);
      out.semantic.push_back(kClassUnlabelled);
      ++next_nan;
      continue;
    }
    out.xyz.insert(out.xyz.end(), scan->xyz.begin() + 3 * src, scan->xyz.begin() + 3 * src + 3);
    out.intensity.push_back(scan->intensity[src]);
    out.ring.push_back(scan->ring[src]);
    out.truth.push_back(scan->truth[src]);
    out.semantic.push_back(scan->semantic[src]);
    ++src;
  }
  *scan = std::move(out);
}

// kAirborne: one vertical pulse per cell of a jittered grid (density points per m2) over
// [-scene_extent, scene_extent]^2, first (highest) surface hit: flat-roofed buildings (some on
// the slopes), cars, bushes, and tree crowns that 35 % of the pulses pass through to the
// ground. Terrain is ground, everything else not. Coordinates in the world frame.
GeneratedScan airborneScan(const SceneParams& p) {
  std::seed_seq seq{p.seed, 0xA1u};
  std::mt19937 rng(seq);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto uni = [&](double lo, double hi) { return lo + (hi - lo) * u01(rng); };
  const double ext = p.scene_extent;
  std::vector<Box> boxes;
  std::vector<Ellipsoid> crowns, bushes;
  const double area = 4.0 * ext * ext;
  if (p.airborne_hall > 0.0) airborneHall(p, &boxes);  // first: the others keep clear
  const std::size_t hall_boxes = boxes.size();
  const int buildings = std::max(2, static_cast<int>(area / 1800.0));
  for (int i = 0; i < buildings; ++i) {
    const double w = uni(8.0, 30.0), d = uni(8.0, 22.0), cx = uni(-ext, ext), cy = uni(-ext, ext);
    const double x0 = cx - w / 2, x1 = cx + w / 2, y0 = cy - d / 2, y1 = cy + d / 2;
    bool overlaps = false;
    for (const Box& b : boxes) {
      overlaps |= x0 < b.hi.x + 4 && x1 > b.lo.x - 4 && y0 < b.hi.y + 4 && y1 > b.lo.y - 4;
    }
    if (overlaps) continue;
    const double base = minGroundOver(p, x0, x1, y0, y1);
    boxes.push_back(
        {{x0, y0, base - 1.0}, {x1, y1, base + uni(3.0, 15.0)}, kWallReflectivity, kClassBuilding});
  }
  const int cars = static_cast<int>(area / 900.0);
  for (int i = 0; i < cars; ++i) {
    const double cx = uni(-ext, ext), cy = uni(-ext, ext);
    const bool along_x = u01(rng) < 0.5;
    const double hx = along_x ? 2.25 : 0.9, hy = along_x ? 0.9 : 2.25;
    const double base = minGroundOver(p, cx - hx, cx + hx, cy - hy, cy + hy);
    boxes.push_back({{cx - hx, cy - hy, base - 0.5},
                     {cx + hx, cy + hy, base + 1.5},
                     kCarReflectivity,
                     kClassCar});
  }
  const int trees = static_cast<int>(area / 250.0);
  for (int i = 0; i < trees; ++i) {
    const double cx = uni(-ext, ext), cy = uni(-ext, ext), r = uni(2.0, 5.0);
    const double rz = uni(2.0, 5.0);
    const double top = airborneHeight(p, cx, cy) + uni(5.0, 18.0);
    crowns.push_back({{cx, cy, top - rz}, {r, r, rz}, kCrownReflectivity, kClassVegetation});
  }
  const int nbush = static_cast<int>(area / 150.0);
  for (int i = 0; i < nbush; ++i) {
    const double cx = uni(-ext, ext), cy = uni(-ext, ext), r = uni(0.6, 1.8), h = uni(0.5, 1.5);
    bushes.push_back(
        {{cx, cy, airborneHeight(p, cx, cy)}, {r, r, h}, kBushReflectivity, kClassVegetation});
  }
  // Top of an ellipsoid at (x, y), or -inf outside its footprint.
  auto ellipsoidTop = [](const Ellipsoid& e, double x, double y, double* depth) {
    const double qx = (x - e.c.x) / e.r.x, qy = (y - e.c.y) / e.r.y, q = 1.0 - qx * qx - qy * qy;
    if (q <= 0.0) return -kNoHit;
    *depth = 2.0 * e.r.z * std::sqrt(q);
    return e.c.z + e.r.z * std::sqrt(q);
  };
  const double step = 1.0 / std::sqrt(p.airborne_density);
  const int n = static_cast<int>(std::floor(2.0 * ext / step));
  std::normal_distribution<double> noise(0.0, p.range_noise_sigma > 0 ? p.range_noise_sigma : 1.0);
  GeneratedScan scan;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = -ext + (i + u01(rng)) * step, y = -ext + (j + u01(rng)) * step;
      const double terrain = airborneHeight(p, x, y);
      double z = terrain;
      std::uint16_t cls = kClassTerrain;
      float refl = kGrassReflectivity;
      std::size_t hit = boxes.size();
      for (std::size_t k = 0; k < boxes.size(); ++k) {
        const Box& b = boxes[k];
        if (x >= b.lo.x && x < b.hi.x && y >= b.lo.y && y < b.hi.y && b.hi.z > z) {
          z = b.hi.z;
          cls = b.cls;
          refl = b.reflectivity;
          hit = k;
        }
      }
      // The hall's boxes come first; its roof strip returns nothing.
      if (hit < hall_boxes && std::fabs(x) < 0.5 * p.airborne_hall_gap) continue;
      const double pass = u01(rng), into = u01(rng);
      for (const auto* list : {&crowns, &bushes}) {
        for (const Ellipsoid& e : *list) {
          double depth = 0.0;
          const double top = ellipsoidTop(e, x, y, &depth);
          // Crowns let 35 % of the pulses through to what is below; bushes none.
          if (top <= z || (list == &crowns && pass < 0.35)) continue;
          // Returns from inside the crown (or bush), never below 0.2 m over the terrain.
          z = std::max(top - (list == &crowns ? 0.5 : 0.15) * into * depth, terrain + 0.2);
          cls = e.cls;
          refl = e.reflectivity;
        }
      }
      if (p.range_noise_sigma > 0.0) z += noise(rng);
      scan.xyz.insert(scan.xyz.end(),
                      {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)});
      scan.intensity.push_back(refl);
      scan.ring.push_back(0);
      scan.truth.push_back(cls == kClassTerrain ? 1 : 0);
      scan.semantic.push_back(cls);
    }
  }
  return scan;
}

// kUav: one line of rays across the track (azimuth +-90 deg), from nadir out to the half angle.
Pattern uavPattern(const SceneParams& p) {
  Pattern pat;
  // The slant range to level ground at the half angle, plus 50 m; past 80 deg (a profile
  // scanner's rays reach the horizon and above) the range at 80 deg.
  const double reach_deg = std::min(p.uav_half_angle_deg, 80.0);
  pat.max_range = p.uav_height / std::cos(reach_deg * kDegToRad) + 50.0;
  pat.azimuth = {0.5 * kPi, 1.5 * kPi};
  const int n =
      std::max(1, static_cast<int>(std::floor(p.uav_half_angle_deg / p.uav_angle_step_deg)));
  for (int k = 0; k < n; ++k) {
    pat.elevation.push_back((-90.0 + (k + 0.5) * p.uav_angle_step_deg) * kDegToRad);
  }
  return pat;
}

// Moves a scan from its scanner frame into the world frame (the scanner at `o`).
void toWorld(GeneratedScan* s, const Vec3& o) {
  for (std::size_t i = 0; i < s->size(); ++i) {
    s->xyz[3 * i] = static_cast<float>(s->xyz[3 * i] + o.x);
    s->xyz[3 * i + 1] = static_cast<float>(s->xyz[3 * i + 1] + o.y);
    s->xyz[3 * i + 2] = static_cast<float>(s->xyz[3 * i + 2] + o.z);
  }
}

void append(GeneratedScan* out, const GeneratedScan& s) {
  out->xyz.insert(out->xyz.end(), s.xyz.begin(), s.xyz.end());
  out->intensity.insert(out->intensity.end(), s.intensity.begin(), s.intensity.end());
  out->ring.insert(out->ring.end(), s.ring.begin(), s.ring.end());
  out->truth.insert(out->truth.end(), s.truth.begin(), s.truth.end());
  out->semantic.insert(out->semantic.end(), s.semantic.begin(), s.semantic.end());
}

// A flight along world x at p.sensor_y: one scan line every uav_line_step over the layout.
GeneratedScan uavScan(const SceneParams& p) {
  const Pattern pat = uavPattern(p);
  const double half = p.crop_half_length > 0.0 ? p.crop_half_length : p.scene_extent;
  const int lines = static_cast<int>(std::floor(2.0 * half / p.uav_line_step)) + 1;
  GeneratedScan out;
  for (int k = 0; k < lines; ++k) {
    SceneParams q = p;
    q.sensor_x = -half + k * p.uav_line_step;
    q.noise_seed = p.noise_seed * 100003u + static_cast<std::uint32_t>(k);
    const Scene scene(q);
    GeneratedScan s = castPattern(q, scene, pat, true);
    toWorld(&s, scene.origin());
    append(&out, s);
  }
  return out;
}

GeneratedScan singleScan(const SceneParams& params);

// Positions along world x merged in the world frame, then cropped and offset.
GeneratedScan registeredScan(const SceneParams& p) {
  GeneratedScan out;
  if (p.mode == SceneParams::Mode::kUav) {
    out = uavScan(p);
  } else {
    for (int k = 0; k < p.positions; ++k) {
      SceneParams q = p;
      q.positions = 1;
      q.world_frame = false;
      q.sensor_x = p.sensor_x + (k - 0.5 * (p.positions - 1)) * p.position_step;
      if (p.follow_track) q.sensor_y = trackCentre(q, q.sensor_x);
      if (p.station_y != 0.0) q.sensor_y = (k % 2 == 0 ? 1.0 : -1.0) * p.station_y;
      q.noise_seed = p.noise_seed * 1009u + static_cast<std::uint32_t>(k);
      GeneratedScan s = singleScan(q);
      thinTo(&s, static_cast<std::size_t>(std::ceil(p.position_keep * s.size())));
      // Airborne tiles are in the world frame already (origin 0).
      toWorld(&s, scannerOrigin(q));
      append(&out, s);
    }
  }
  if (p.airborne_extra > 0.0) {
    SceneParams q = p;
    q.mode = SceneParams::Mode::kUav;
    q.uav_half_angle_deg = 10.0;
    q.uav_line_step = 1.0;
    GeneratedScan air = uavScan(q);
    thinTo(&air, static_cast<std::size_t>(p.airborne_extra / (1.0 - p.airborne_extra) *
                                          static_cast<double>(out.size())));
    append(&out, air);
  }
  // Crop and offset in place.
  std::size_t w = 0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    const float x = out.xyz[3 * i], y = out.xyz[3 * i + 1], z = out.xyz[3 * i + 2];
    if (p.crop_half_width > 0.0 && std::fabs(y) > p.crop_half_width) continue;
    if (p.crop_half_length > 0.0 && std::fabs(x) > p.crop_half_length) continue;
    out.xyz[3 * w] = static_cast<float>(x + p.world_offset_x);
    out.xyz[3 * w + 1] = static_cast<float>(y + p.world_offset_y);
    out.xyz[3 * w + 2] = static_cast<float>(z + p.world_offset_z);
    out.intensity[w] = out.intensity[i];
    out.ring[w] = out.ring[i];
    out.truth[w] = out.truth[i];
    out.semantic[w] = out.semantic[i];
    ++w;
  }
  out.xyz.resize(3 * w);
  out.intensity.resize(w);
  out.ring.resize(w);
  out.truth.resize(w);
  out.semantic.resize(w);
  return out;
}

// One scan in its scanner frame (kAirborne: its world frame).
GeneratedScan singleScan(const SceneParams& params) {
  const Scene scene(params);
  GeneratedScan scan;
  if (params.mode == SceneParams::Mode::kAirborne) {
    scan = airborneScan(params);
  } else if (params.mode == SceneParams::Mode::kLidar64) {
    scan = castPattern(params, scene, lidarPattern(params), true);
  } else if (params.mode == SceneParams::Mode::kRosette) {
    scan = castPattern(params, scene, rosettePattern(params), true);
  } else {
    // Size the ray grid from the hit ratio of a coarse pre-pass so that the returns come close
    // to the budget without exceeding it (any excess is thinned evenly).
    const double budget = static_cast<double>(params.tls_points);
    const Pattern coarse = tlsPattern(params, std::max(budget / 16.0, 4000.0));
    const double coarse_rays =
        static_cast<double>(coarse.azimuth.size()) * static_cast<double>(coarse.elevation.size());
    const double coarse_hits =
        static_cast<double>(castPattern(params, scene, coarse, false).size());
    const double ratio = coarse_hits > 0.0 ? coarse_hits / coarse_rays : 1.0;
    const double rays = std::min(0.99 * budget / std::max(ratio, 0.05), 20.0 * budget);
    scan = castPattern(params, scene, tlsPattern(params, rays), true);
    thinTo(&scan, params.tls_points);
  }
  return scan;
}

}  // namespace
}  // namespace scene

void SceneParams::validate() const {
  checkRange("sensor_height", sensor_height, 0.2, 10.0, "m");
  checkRange("tripod_height", tripod_height, 0.2, 10.0, "m");
  checkRange("sensor_x", sensor_x, -1e5, 1e5, "m");
  checkRange("sensor_y", sensor_y, -1e5, 1e5, "m");
  checkRange("beams", beams, 1, 1024, "");
  checkRange("azimuth_steps", azimuth_steps, 16, 36000, "");
  checkRange("vertical_min_deg", vertical_min_deg, -89.0, 89.0, "deg");
  checkRange("vertical_max_deg", vertical_max_deg, vertical_min_deg, 89.0, "deg");
  checkRange("min_range", min_range, 0.0, 10.0, "m");
  checkRange("lidar_max_range", lidar_max_range, min_range + 0.1, 1000.0, "m");
  checkRange("tls_points", static_cast<double>(tls_points), 1000.0, 1e8, "points");
  checkRange("tls_min_elevation_deg", tls_min_elevation_deg, -89.0, 89.0, "deg");
  checkRange("tls_max_elevation_deg", tls_max_elevation_deg, tls_min_elevation_deg + 1.0, 89.0,
             "deg");
  checkRange("tls_max_range", tls_max_range, min_range + 0.1, 2000.0, "m");
  checkRange("range_noise_sigma", range_noise_sigma, 0.0, 1.0, "m");
  checkRange("nan_points", static_cast<double>(nan_points), 0.0, 1e6, "points");
  checkRange("slope_x", slope_x, -0.3, 0.3, "m/m");
  checkRange("slope_y", slope_y, -0.3, 0.3, "m/m");
  checkRange("curb_y", curb_y, 1.0, 50.0, "m");
  checkRange("curb_height", curb_height, 0.0, 1.0, "m");
  checkRange("ramp_start_x", ramp_start_x, -1e4, 1e4, "m");
  checkRange("ramp_end_x", ramp_end_x, ramp_start_x + 0.5, 1e4, "m");
  checkRange("ramp_height", ramp_height, -20.0, 20.0, "m");
  checkRange("scene_extent", scene_extent, 10.0, 2000.0, "m");
  checkRange("grass_roughness", grass_roughness, 0.0, 1.0, "m");
  checkRange("airborne_density", airborne_density, 0.05, 100.0, "points/m2");
  checkRange("uav_height", uav_height, 2.0, 1000.0, "m");
  checkRange("uav_half_angle_deg", uav_half_angle_deg, 1.0, 180.0, "deg");
  checkRange("uav_line_step", uav_line_step, 0.02, 100.0, "m");
  checkRange("uav_angle_step_deg", uav_angle_step_deg, 0.01, 10.0, "deg");
  checkRange("rosette_fov_deg", rosette_fov_deg, 1.0, 120.0, "deg");
  checkRange("rosette_rays", static_cast<double>(rosette_rays), 100.0, 1e7, "rays");
  checkRange("rosette_pitch_deg", rosette_pitch_deg, -60.0, 60.0, "deg");
  checkRange("positions", positions, 1, 1000, "");
  checkRange("position_step", position_step, 0.1, 1000.0, "m");
  checkRange("position_keep", position_keep, 0.001, 1.0, "");
  checkRange("station_y", station_y, -50.0, 50.0, "m");
  checkRange("world_offset_x", world_offset_x, -1e5, 1e5, "m");
  checkRange("world_offset_y", world_offset_y, -1e5, 1e5, "m");
  checkRange("world_offset_z", world_offset_z, -1e4, 1e4, "m");
  checkRange("crop_half_width", crop_half_width, 0.0, 1e4, "m");
  checkRange("crop_half_length", crop_half_length, 0.0, 1e4, "m");
  checkRange("airborne_extra", airborne_extra, 0.0, 0.5, "");
  checkRange("airborne_hall", airborne_hall, 0.0, 1000.0, "m");
  checkRange("airborne_hall_step", airborne_hall_step, 0.0, 6.0, "m");
  checkRange("airborne_hall_gap", airborne_hall_gap, 0.0, 40.0, "m");
  checkRange("second_returns", second_returns, 0.0, 1.0, "");
  checkRange("ceiling_height", ceiling_height, 1.5, 30.0, "m");
  checkRange("beside_car", beside_car, 0.0, 30.0, "m");
  checkRange("mount_roll_deg", mount_roll_deg, -90.0, 90.0, "deg");
  checkRange("mount_pitch_deg", mount_pitch_deg, -90.0, 90.0, "deg");
  // A frame on the ground below the scanner and a tilted mount both describe one scan.
  const char* one_scan = base_frame ? "parameter 'base_frame'"
                         : mount_roll_deg != 0.0 || mount_pitch_deg != 0.0
                             ? "parameters 'mount_roll_deg', 'mount_pitch_deg'"
                             : nullptr;
  if (one_scan && (sceneInWorldFrame(*this) || mode == Mode::kAirborne)) {
    throw std::invalid_argument(std::string(one_scan) +
                                ": only for one scan of a ground-level scanner in its own frame "
                                "(not with world_frame, positions > 1, airborne or uav)");
  }
}

GeneratedScan generateScene(const SceneParams& params) {
  params.validate();
  GeneratedScan scan =
      sceneInWorldFrame(params) ? scene::registeredScan(params) : scene::singleScan(params);
  if (params.base_frame) {  // the scanner's height above the ground below it, onto every z
    const scene::Vec3 o = scene::scannerOrigin(params);
    const double up = o.z - scene::worldGroundHeight(params, o.x, o.y);
    for (std::size_t i = 0; i < scan.size(); ++i) {
      scan.xyz[3 * i + 2] = static_cast<float>(scan.xyz[3 * i + 2] + up);
    }
  }
  scene::turnToMount(params, scan.xyz.data(), scan.size());
  scene::insertNans(&scan, params.nan_points);
  return scan;
}

bool sceneInWorldFrame(const SceneParams& params) {
  return params.world_frame || params.positions > 1 || params.mode == SceneParams::Mode::kUav;
}

double sceneGroundHeight(const SceneParams& params, double x, double y) {
  if (params.mount_roll_deg != 0.0 || params.mount_pitch_deg != 0.0) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  if (sceneInWorldFrame(params)) {
    return scene::worldGroundHeight(params, x - params.world_offset_x, y - params.world_offset_y) +
           params.world_offset_z;
  }
  const scene::Vec3 o = scene::scannerOrigin(params);
  // base_frame: z from the ground below the scanner rather than from the scanner.
  const double z0 = params.base_frame ? scene::worldGroundHeight(params, o.x, o.y) : o.z;
  return scene::worldGroundHeight(params, x + o.x, y + o.y) - z0;
}

}  // namespace ground_filter
