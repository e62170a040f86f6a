#include "ground_filter/scene_generator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "ground_filter/param_parse.h"

namespace ground_filter {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
constexpr double kNoHit = std::numeric_limits<double>::infinity();

// Reflectivity-like intensities per material.
constexpr float kRoadReflectivity = 0.18f;
constexpr float kSidewalkReflectivity = 0.32f;
constexpr float kWallReflectivity = 0.45f;
constexpr float kCarReflectivity = 0.70f;
constexpr float kPoleReflectivity = 0.55f;
constexpr float kTrunkReflectivity = 0.20f;
constexpr float kCrownReflectivity = 0.28f;

struct Vec3 {
  double x, y, z;
};

// Axis-aligned box (buildings, car bodies and cabins).
struct Box {
  Vec3 lo, hi;
  float reflectivity;
  std::uint16_t cls;
};

// Vertical cylinder between z0 and z1 (poles, trunks).
struct Cylinder {
  double cx, cy, r, z0, z1;
  float reflectivity;
  std::uint16_t cls;
};

// Axis-aligned ellipsoid (tree crowns).
struct Ellipsoid {
  Vec3 c, r;
  float reflectivity;
  std::uint16_t cls;
};

enum class Shape : std::uint8_t { kBox, kCylinder, kEllipsoid };

// An object's place in its shape array and its azimuth sector seen from the scanner, so that
// each azimuth column only tests the few objects in front of it.
struct SectorEntry {
  Shape shape;
  std::uint32_t index;
  double center_az;   // [rad]
  double half_width;  // [rad]; >= pi means "all around"
};

// One planar piece of the terrain: z = a x + b y + c over [x0, x1) x [y0, y1) (world frame).
struct TerrainPatch {
  double a, b, c;
  double x0, x1, y0, y1;
  float reflectivity;
  std::uint16_t cls;
};

struct Hit {
  double t = kNoHit;
  float reflectivity = 0.f;
  bool ground = false;
  std::uint16_t cls = kClassUnlabelled;
  float roughness = 0.f;  // half-range of the vertical noise of this surface [m]
};

constexpr float kGrassReflectivity = 0.25f;
constexpr float kDirtReflectivity = 0.30f;
constexpr float kBushReflectivity = 0.35f;

double rampOffset(const SceneParams& p, double x) {
  if (x <= p.ramp_start_x) return 0.0;
  if (x >= p.ramp_end_x) return p.ramp_height;
  return p.ramp_height * (x - p.ramp_start_x) / (p.ramp_end_x - p.ramp_start_x);
}

double roadHeight(const SceneParams& p, double x, double y) {
  return p.slope_x * x + p.slope_y * y + rampOffset(p, x);
}

// A per-seed phase in [0, 2 pi) for term k of the natural terrains (splitmix64 of seed and k).
double phase(const SceneParams& p, std::uint64_t k) {
  std::uint64_t z = (static_cast<std::uint64_t>(p.seed) << 8) + k + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return 2.0 * kPi * static_cast<double>(z >> 11) * (1.0 / 9007199254740992.0);
}

// kVerge: road |y| <= 4 with 2 % camber; y > 4 a grass verge falling away at 17-33 % for
// 3.5 m, then a lawn rising at 6 %; y < -4 a 0.12 m kerb, a 2 m sidewalk and a lawn rising at
// 13-23 % for 8 m, then level.
constexpr double kVergeRoadHalfWidth = 4.0;
constexpr double kVergeSidewalkEnd = -6.0;

double vergeHeight(const SceneParams& p, double x, double y) {
  const double road = p.slope_x * x;
  const double edge = road - 0.02 * kVergeRoadHalfWidth;
  if (y > kVergeRoadHalfWidth) {
    const double s = 0.25 * (1.0 + 0.3 * std::sin(x / 13.0 + phase(p, 0)));
    const double yy = y - kVergeRoadHalfWidth;
    return edge - s * std::min(yy, 3.5) + 0.06 * std::max(yy - 3.5, 0.0);
  }
  if (y < -kVergeRoadHalfWidth) {
    const double walk = edge + 0.12;
    if (y >= kVergeSidewalkEnd) return walk;
    const double s = 0.18 * (1.0 + 0.3 * std::sin(x / 17.0 + phase(p, 1)));
    return walk + s * std::min(kVergeSidewalkEnd - y, 8.0);
  }
  return road - 0.02 * std::fabs(y);
}

// kOffroad: rolling grassland, slopes mostly under 20 %.
double offroadHeight(const SceneParams& p, double x, double y) {
  return 0.6 * std::sin(x / 8.0 + phase(p, 0)) * std::cos(y / 10.0 + phase(p, 1)) +
         0.4 * std::sin((x + 1.7 * y) / 15.0 + phase(p, 2)) +
         0.15 * std::sin((2.0 * x - y) / 4.5 + phase(p, 3)) + p.slope_x * x;
}

// Centre line of the dirt track (kOffroad) or trail (kTrail), through y = 0 at x = 0.
double trackCentre(const SceneParams& p, double x) {
  if (p.layout == SceneParams::Layout::kTrail) {
    return 4.0 * (std::sin(x / 25.0 + phase(p, 4)) - std::sin(phase(p, 4)));
  }
  return 1.5 * (std::sin(x / 12.0 + phase(p, 4)) - std::sin(phase(p, 4)));
}

constexpr double kTrackHalfWidth = 1.3;

// kTrail: hills of a few metres, slopes up to about 25 %.
double trailHeight(const SceneParams& p, double x, double y) {
  return 2.2 * std::sin(x / 24.0 + phase(p, 0)) +
         1.3 * std::cos(y / 15.0 + x / 40.0 + phase(p, 1)) +
         0.45 * std::sin((x - y) / 8.0 + phase(p, 2));
}

// kAirborne: hills of several metres (slopes up to ~30 %) and an embankment that rises 5 m
// over 9 m (about 55 %) along a line across the tile.
double airborneHeight(const SceneParams& p, double x, double y) {
  const double hills = 6.0 * std::sin(x / 35.0 + phase(p, 0)) * std::cos(y / 45.0 + phase(p, 1)) +
                       2.5 * std::sin((x + y) / 20.0 + phase(p, 2)) +
                       0.6 * std::sin((x - 2.0 * y) / 7.0 + phase(p, 3));
  const double a = phase(p, 4);
  const double u = std::cos(a) * x + std::sin(a) * y - 20.0 * std::sin(phase(p, 5));
  const double t = std::max(0.0, std::min(1.0, (u + 4.5) / 9.0));
  return hills + 5.0 * t * t * (3.0 - 2.0 * t);  // smoothstep: steepest (~0.8) mid-slope
}

double worldGroundHeight(const SceneParams& p, double x, double y) {
  if (p.mode == SceneParams::Mode::kAirborne) return airborneHeight(p, x, y);
  switch (p.layout) {
    case SceneParams::Layout::kVerge:
      return vergeHeight(p, x, y);
    case SceneParams::Layout::kOffroad:
      return offroadHeight(p, x, y);
    case SceneParams::Layout::kTrail:
      return trailHeight(p, x, y);
    case SceneParams::Layout::kStreet:
      break;
  }
  return roadHeight(p, x, y) + (y >= p.curb_y ? p.curb_height : 0.0);
}

// Surface class of the non-street terrains at (x, y) (world frame).
std::uint16_t naturalClass(const SceneParams& p, double x, double y) {
  if (p.layout == SceneParams::Layout::kVerge) {
    if (std::fabs(y) <= kVergeRoadHalfWidth) return kClassRoad;
    if (y < -kVergeRoadHalfWidth && y >= kVergeSidewalkEnd) return kClassSidewalk;
    return kClassTerrain;
  }
  return std::fabs(y - trackCentre(p, x)) < kTrackHalfWidth ? kClassOtherGround : kClassTerrain;
}

Vec3 scannerOrigin(const SceneParams& p) {
  if (p.mode == SceneParams::Mode::kAirborne) return {0.0, 0.0, 0.0};  // world frame
  const double h = p.mode == SceneParams::Mode::kTls ? p.tripod_height : p.sensor_height;
  return {p.sensor_x, p.sensor_y, worldGroundHeight(p, p.sensor_x, p.sensor_y) + h};
}

// Lowest terrain height over a footprint (terrain is piecewise linear: a 5x5 sample plus the
// corners is exact enough to bury object bottoms).
double minGroundOver(const SceneParams& p, double x0, double x1, double y0, double y1) {
  double m = kNoHit;
  for (int i = 0; i <= 4; ++i) {
    for (int j = 0; j <= 4; ++j) {
      m = std::min(m, worldGroundHeight(p, x0 + (x1 - x0) * i / 4.0, y0 + (y1 - y0) * j / 4.0));
    }
  }
  return m;
}

class Scene {
 public:
  explicit Scene(const SceneParams& p) : p_(p), origin_(scannerOrigin(p)) {
    if (p.layout == SceneParams::Layout::kStreet) {
      buildTerrain();
      buildLayout();
    } else {
      buildNaturalLayout();
    }
    buildSectors();
  }

  const Vec3& origin() const { return origin_; }

  // Objects whose azimuth sector contains `az`.
  void candidates(double az, std::vector<const SectorEntry*>* out) const {
    out->clear();
    for (const SectorEntry& e : sectors_) {
      if (e.half_width >= kPi) {
        out->push_back(&e);
        continue;
      }
      double d = std::fabs(az - e.center_az);
      if (d > kPi) d = 2.0 * kPi - d;
      if (d <= e.half_width + 1e-6) out->push_back(&e);
    }
  }

  // Nearest hit along origin + t * d (unit d) with t in (t_min, t_max].
  Hit cast(const Vec3& d, const std::vector<const SectorEntry*>& objects, double t_min,
           double t_max) const {
    Hit best;
    best.t = t_max;
    bool any = false;
    for (const TerrainPatch& tp : terrain_) {
      const double denom = d.z - tp.a * d.x - tp.b * d.y;
      if (denom >= 0.0) continue;  // the terrain is only seen from above
      const double t = (tp.a * origin_.x + tp.b * origin_.y + tp.c - origin_.z) / denom;
      if (t <= t_min || t > best.t) continue;
      const double hx = origin_.x + t * d.x;
      const double hy = origin_.y + t * d.y;
      if (hx < tp.x0 || hx >= tp.x1 || hy < tp.y0 || hy >= tp.y1) continue;
      best = {t, tp.reflectivity, true, tp.cls};
      any = true;
    }
    // Vertical curb face between road and sidewalk.
    if (d.y != 0.0 && p_.layout == SceneParams::Layout::kStreet) {
      const double t = (p_.curb_y - origin_.y) / d.y;
      if (t > t_min && t <= best.t) {
        const double hx = origin_.x + t * d.x;
        const double hz = origin_.z + t * d.z;
        const double base = roadHeight(p_, hx, p_.curb_y);
        if (hz >= base && hz <= base + p_.curb_height) {
          best = {t, kSidewalkReflectivity, true, kClassSidewalk};
          any = true;
        }
      }
    }
    for (const SectorEntry* e : objects) {
      double t = kNoHit;
      float refl = 0.f;
      std::uint16_t cls = kClassUnlabelled;
      switch (e->shape) {
        case Shape::kBox:
          t = hitBox(boxes_[e->index], d, t_min);
          refl = boxes_[e->index].reflectivity;
          cls = boxes_[e->index].cls;
          break;
        case Shape::kCylinder:
          t = hitCylinder(cylinders_[e->index], d, t_min);
          refl = cylinders_[e->index].reflectivity;
          cls = cylinders_[e->index].cls;
          break;
        case Shape::kEllipsoid:
          t = hitEllipsoid(ellipsoids_[e->index], d, t_min);
          refl = ellipsoids_[e->index].reflectivity;
          cls = ellipsoids_[e->index].cls;
          break;
      }
      if (t <= best.t) {
        best = {t, refl, false, cls};
        any = true;
      }
    }
    if (p_.layout != SceneParams::Layout::kStreet) {
      // Height-field terrain: nearer than the nearest object?
      const double t = marchTerrain(d, t_min, best.t);
      if (t != kNoHit) {
        const double hx = origin_.x + t * d.x, hy = origin_.y + t * d.y;
        const std::uint16_t cls = naturalClass(p_, hx, hy);
        const double rough = cls == kClassTerrain       ? p_.grass_roughness
                             : cls == kClassOtherGround ? 0.2 * p_.grass_roughness
                                                        : 0.0;
        const float refl = cls == kClassTerrain       ? kGrassReflectivity
                           : cls == kClassOtherGround ? kDirtReflectivity
                           : cls == kClassSidewalk    ? kSidewalkReflectivity
                                                      : kRoadReflectivity;
        best = {t, refl, true, cls, static_cast<float>(rough)};
        any = true;
      }
    }
    if (!any) best.t = kNoHit;
    return best;
  }

 private:
  void buildTerrain() {
    const double inf = std::numeric_limits<double>::infinity();
    const double xs[4] = {-inf, p_.ramp_start_x, p_.ramp_end_x, inf};
    const double ys[3] = {-inf, p_.curb_y, inf};
    const double ramp_slope = p_.ramp_height / (p_.ramp_end_x - p_.ramp_start_x);
    for (int i = 0; i < 3; ++i) {
      // Road level on this x interval: slope_x x + slope_y y + offset.
      double a = p_.slope_x, c = 0.0;
      if (i == 1) {
        a += ramp_slope;
        c = -ramp_slope * p_.ramp_start_x;
      } else if (i == 2) {
        c = p_.ramp_height;
      }
      for (int j = 0; j < 2; ++j) {
        const bool sidewalk = j == 1;
        terrain_.push_back({a, p_.slope_y, c + (sidewalk ? p_.curb_height : 0.0), xs[i], xs[i + 1],
                            ys[j], ys[j + 1], sidewalk ? kSidewalkReflectivity : kRoadReflectivity,
                            sidewalk ? kClassSidewalk : kClassRoad});
      }
    }
  }

  void addBox(double x0, double x1, double y0, double y1, double z0, double z1, float refl,
              std::uint16_t cls) {
    boxes_.push_back({{x0, y0, z0}, {x1, y1, z1}, refl, cls});
  }

  void addCar(std::mt19937& rng, double xc, double yc) {
    std::uniform_real_distribution<double> len(4.0, 4.8), wid(1.7, 1.9), hgt(0.85, 1.0),
        roof(1.35, 1.55);
    const double l = len(rng), w = wid(rng);
    const double x0 = xc - l / 2, x1 = xc + l / 2, y0 = yc - w / 2, y1 = yc + w / 2;
    const double g = worldGroundHeight(p_, xc, yc);
    const double bottom = minGroundOver(p_, x0, x1, y0, y1) - 0.3;
    const double body_top = g + hgt(rng);
    addBox(x0, x1, y0, y1, bottom, body_top, kCarReflectivity, kClassCar);
    // Cabin: narrower box with the roof on top.
    addBox(x0 + 0.25 * l, x1 - 0.2 * l, y0 + 0.1, y1 - 0.1, body_top - 0.01, g + roof(rng),
           kCarReflectivity, kClassCar);
  }

  void addTree(std::mt19937& rng, double x, double y) {
    std::uniform_real_distribution<double> crown_r(2.6, 3.4), crown_h(1.4, 2.2),
        crown_base(2.0, 2.5), trunk_r(0.18, 0.3);
    const double g = worldGroundHeight(p_, x, y);
    const double rz = crown_h(rng), rxy = crown_r(rng);
    const double cz = g + crown_base(rng) + rz;  // the canopy starts ~2 m above the ground
    ellipsoids_.push_back({{x, y, cz}, {rxy, rxy, rz}, kCrownReflectivity, kClassVegetation});
    const double tr = trunk_r(rng);
    cylinders_.push_back({x, y, tr, minGroundOver(p_, x - tr, x + tr, y - tr, y + tr) - 0.2, cz,
                          kTrunkReflectivity, kClassTrunk});
  }

  void addPole(std::mt19937& rng, double x, double y) {
    std::uniform_real_distribution<double> height(5.0, 8.0);
    const double r = 0.1;
    cylinders_.push_back({x, y, r, minGroundOver(p_, x - r, x + r, y - r, y + r) - 0.2,
                          worldGroundHeight(p_, x, y) + height(rng), kPoleReflectivity,
                          kClassPole});
  }

  // Row of buildings between y_near and y_far (y_far beyond y_near, on either side).
  void addBuildingRow(std::mt19937& rng, double y_near, double direction) {
    std::uniform_real_distribution<double> gap(2.0, 9.0), length(8.0, 22.0), depth(8.0, 14.0),
        height(5.0, 16.0), setback(0.0, 2.5);
    const double e = p_.scene_extent;
    for (double x = -e + gap(rng); x < e;) {
      const double l = length(rng);
      const double ya = y_near + direction * setback(rng);
      const double yb = ya + direction * depth(rng);
      const double y0 = std::min(ya, yb), y1 = std::max(ya, yb);
      const double x1 = std::min(x + l, e);
      addBox(x, x1, y0, y1, minGroundOver(p_, x, x1, y0, y1) - 0.5,
             worldGroundHeight(p_, 0.5 * (x + x1), 0.5 * (y0 + y1)) + height(rng),
             kWallReflectivity, kClassBuilding);
      x = x1 + gap(rng);
    }
  }

  void buildLayout() {
    std::mt19937 rng(p_.seed);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    const double e = p_.scene_extent;
    const double cy = p_.curb_y;

    addBuildingRow(rng, cy + 4.5, +1.0);  // behind the 4 m sidewalk
    addBuildingRow(rng, -15.0, -1.0);     // behind the verge on the other side

    // Parked cars along the curb; oncoming traffic in the far lane.
    std::uniform_real_distribution<double> parked_gap(1.5, 10.0), lane_gap(12.0, 35.0);
    for (double x = -e + parked_gap(rng); x < e - 3.0; x += 5.0 + parked_gap(rng)) {
      if (u01(rng) < 0.75) addCar(rng, x, cy - 1.25);
    }
    for (double x = -e + lane_gap(rng); x < e - 3.0; x += lane_gap(rng)) {
      addCar(rng, x, -3.6);
    }

    // Poles on the sidewalk and the verge.
    std::uniform_real_distribution<double> pole_gap(12.0, 25.0);
    for (double x = -e + pole_gap(rng); x < e; x += pole_gap(rng)) addPole(rng, x, cy + 0.6);
    for (double x = -e + 2.0 * pole_gap(rng); x < e; x += 2.0 * pole_gap(rng)) {
      addPole(rng, x, -7.0);
    }

    // Trees whose crowns overhang the road and the sidewalk; one always just ahead of x = 0.
    std::uniform_real_distribution<double> tree_gap(14.0, 30.0), jitter(-2.0, 2.0);
    addTree(rng, 9.0 + jitter(rng), cy + 2.0);
    for (double x = 9.0 + tree_gap(rng); x < e; x += tree_gap(rng)) addTree(rng, x, cy + 2.0);
    for (double x = 9.0 - tree_gap(rng); x > -e; x -= tree_gap(rng)) addTree(rng, x, cy + 2.0);
    for (double x = -e + tree_gap(rng); x < e; x += tree_gap(rng)) addTree(rng, x, -9.0);
  }

  // A bush (or undergrowth clump) of height h above the ground at its centre and radius r: an
  // ellipsoid whose lower part is buried, so it grows out of the ground on any slope.
  void addBush(double x, double y, double h, double r) {
    const double rz = 0.65 * h;
    ellipsoids_.push_back({{x, y, worldGroundHeight(p_, x, y) + h - rz},
                           {r, r, rz},
                           kBushReflectivity,
                           kClassVegetation});
  }

  // Places `count` objects uniformly in |x| <= ex, |y - track| in [near, far] (either side; far
  // <= 0 means anywhere in |y| <= ex), away from the scanner's world position.
  template <typename Place>
  void scatter(std::mt19937& rng, int count, double ex, double near, double far, Place place) {
    std::uniform_real_distribution<double> ux(-ex, ex), uside(near, far > 0.0 ? far : ex),
        uy(-ex, ex), coin(0.0, 1.0);
    for (int i = 0; i < count; ++i) {
      const double x = ux(rng);
      double y;
      if (far > 0.0) {
        const double off = uside(rng);
        y = trackCentre(p_, x) + (coin(rng) < 0.5 ? -off : off);
      } else {
        y = uy(rng);
        if (std::fabs(y - trackCentre(p_, x)) < near) continue;
      }
      if (std::hypot(x - p_.sensor_x, y - p_.sensor_y) < 3.0) continue;
      place(x, y);
    }
  }

  void buildNaturalLayout() {
    std::mt19937 rng(p_.seed);
    std::uniform_real_distribution<double> bush_h(0.3, 1.0), bush_r(0.3, 1.2), under_h(0.12, 0.3),
        under_r(0.2, 0.6);
    auto bush = [&](double x, double y) {
      const double h = bush_h(rng);
      addBush(x, y, h, bush_r(rng));
    };
    auto under = [&](double x, double y) {
      const double h = under_h(rng);
      addBush(x, y, h, under_r(rng));
    };
    auto tree = [&](double x, double y) { addTree(rng, x, y); };
    if (p_.layout == SceneParams::Layout::kVerge) {
      const double e = std::min(p_.scene_extent, 70.0);
      std::uniform_real_distribution<double> ux(-e, e), verge_y(5.0, 20.0), lawn_y(-22.0, -7.0),
          car_gap(8.0, 25.0);
      for (int i = 0; i < 60; ++i) {
        const double x = ux(rng), y = verge_y(rng);
        bush(x, y);
      }
      for (int i = 0; i < 60; ++i) {
        const double x = ux(rng), y = lawn_y(rng);
        bush(x, y);
      }
      // Oncoming lane (y = 2.6) ahead, the scanner's lane (y = 0) behind it; no car closer to
      // the scanner's own vehicle than a real one could be.
      for (double x = -e + car_gap(rng); x < e; x += car_gap(rng)) {
        const double y = x > p_.sensor_x ? 2.6 : 0.0;
        if (std::fabs(x - p_.sensor_x) < (y > 0.0 ? 3.0 : 8.0)) continue;
        addCar(rng, x, y);
      }
      std::uniform_real_distribution<double> tree_gap(10.0, 25.0);
      for (double x = -e + tree_gap(rng); x < e; x += tree_gap(rng)) addTree(rng, x, 13.0);
      for (double x = -e + tree_gap(rng); x < e; x += tree_gap(rng)) addTree(rng, x, -17.0);
      std::uniform_real_distribution<double> pole_gap(15.0, 30.0);
      for (double x = -e + pole_gap(rng); x < e; x += pole_gap(rng)) addPole(rng, x, -5.5);
      addBuildingRow(rng, 26.0, +1.0);
      addBuildingRow(rng, -26.0, -1.0);
    } else if (p_.layout == SceneParams::Layout::kOffroad) {
      scatter(rng, 250, 55.0, 1.8, 0.0, bush);
      scatter(rng, 900, 35.0, 1.8, 0.0, under);
      scatter(rng, 15, 60.0, 6.0, 0.0, tree);
    } else {  // kTrail
      scatter(rng, 200, 60.0, 2.0, 15.0, bush);
      scatter(rng, 400, 40.0, 1.8, 12.0, under);
      scatter(rng, 25, 60.0, 6.0, 30.0, tree);
    }
  }

  // First crossing of the ray origin + t d below the height-field terrain in (t_min, t_max]:
  // steps that grow with the range (the hills are metres wide), then bisection.
  double marchTerrain(const Vec3& d, double t_min, double t_max) const {
    auto above = [&](double t) {
      return origin_.z + t * d.z - worldGroundHeight(p_, origin_.x + t * d.x, origin_.y + t * d.y);
    };
    // The natural terrains are never steeper than kMaxGrade (kerb steps only rise, so a long
    // step cannot jump over them): a ray h above the terrain cannot reach it within
    // h / (kMaxGrade |d_xy| + max(0, -d_z)).
    constexpr double kMaxGrade = 0.5;
    const double climb = kMaxGrade * std::hypot(d.x, d.y) + std::max(0.0, -d.z);
    double t0 = t_min;
    double h0 = above(t0);
    if (!(t_max > t0) || h0 <= 0.0) return kNoHit;
    while (t0 < t_max) {
      const double t1 = std::min(t0 + std::max(0.04 + 0.008 * t0, h0 / climb), t_max);
      const double h1 = above(t1);
      if (h1 <= 0.0) {
        double lo = t0, hi = t1;
        for (int it = 0; it < 40; ++it) {
          const double mid = 0.5 * (lo + hi);
          (above(mid) > 0.0 ? lo : hi) = mid;
        }
        return hi;
      }
      t0 = t1;
      h0 = h1;
    }
    return kNoHit;
  }

  void addSector(Shape shape, std::uint32_t index, double x0, double x1, double y0, double y1) {
    const double ox = origin_.x, oy = origin_.y;
    SectorEntry s{shape, index, 0.0, kPi};
    if (!(ox >= x0 && ox <= x1 && oy >= y0 && oy <= y1)) {
      // Footprint outside the scanner: its corners span less than pi around the centre angle.
      s.center_az = std::atan2(0.5 * (y0 + y1) - oy, 0.5 * (x0 + x1) - ox);
      double half = 0.0;
      const double cx[4] = {x0, x1, x0, x1}, cy[4] = {y0, y0, y1, y1};
      for (int k = 0; k < 4; ++k) {
        double d = std::atan2(cy[k] - oy, cx[k] - ox) - s.center_az;
        while (d > kPi) d -= 2.0 * kPi;
        while (d < -kPi) d += 2.0 * kPi;
        half = std::max(half, std::fabs(d));
      }
      s.half_width = half;
    }
    sectors_.push_back(s);
  }

  void buildSectors() {
    for (std::uint32_t i = 0; i < boxes_.size(); ++i) {
      const Box& b = boxes_[i];
      addSector(Shape::kBox, i, b.lo.x, b.hi.x, b.lo.y, b.hi.y);
    }
    for (std::uint32_t i = 0; i < cylinders_.size(); ++i) {
      const Cylinder& c = cylinders_[i];
      addSector(Shape::kCylinder, i, c.cx - c.r, c.cx + c.r, c.cy - c.r, c.cy + c.r);
    }
    for (std::uint32_t i = 0; i < ellipsoids_.size(); ++i) {
      const Ellipsoid& el = ellipsoids_[i];
      addSector(Shape::kEllipsoid, i, el.c.x - el.r.x, el.c.x + el.r.x, el.c.y - el.r.y,
                el.c.y + el.r.y);
    }
  }

  double hitBox(const Box& b, const Vec3& d, double t_min) const {
    double t0 = -kNoHit, t1 = kNoHit;
    const double o[3] = {origin_.x, origin_.y, origin_.z};
    const double dd[3] = {d.x, d.y, d.z};
    const double lo[3] = {b.lo.x, b.lo.y, b.lo.z}, hi[3] = {b.hi.x, b.hi.y, b.hi.z};
    for (int k = 0; k < 3; ++k) {
      if (dd[k] == 0.0) {
        if (o[k] < lo[k] || o[k] > hi[k]) return kNoHit;
        continue;
      }
      double ta = (lo[k] - o[k]) / dd[k], tb = (hi[k] - o[k]) / dd[k];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
      if (t0 > t1) return kNoHit;
    }
    return t0 > t_min ? t0 : kNoHit;  // from inside a box: no return
  }

  double hitCylinder(const Cylinder& c, const Vec3& d, double t_min) const {
    double best = kNoHit;
    const double ox = origin_.x - c.cx, oy = origin_.y - c.cy;
    const double a = d.x * d.x + d.y * d.y;
    if (a > 0.0) {
      const double b = ox * d.x + oy * d.y;
      const double cc = ox * ox + oy * oy - c.r * c.r;
      const double disc = b * b - a * cc;
      if (disc >= 0.0) {
        const double t = (-b - std::sqrt(disc)) / a;
        const double z = origin_.z + t * d.z;
        if (t > t_min && z >= c.z0 && z <= c.z1) best = t;
      }
    }
    if (d.z < 0.0) {  // top cap, seen from above
      const double t = (c.z1 - origin_.z) / d.z;
      const double x = ox + t * d.x, y = oy + t * d.y;
      if (t > t_min && t < best && x * x + y * y <= c.r * c.r) best = t;
    }
    return best;
  }

  double hitEllipsoid(const Ellipsoid& e, const Vec3& d, double t_min) const {
    // Scale to the unit sphere.
    const double ox = (origin_.x - e.c.x) / e.r.x, oy = (origin_.y - e.c.y) / e.r.y,
                 oz = (origin_.z - e.c.z) / e.r.z;
    const double dx = d.x / e.r.x, dy = d.y / e.r.y, dz = d.z / e.r.z;
    const double a = dx * dx + dy * dy + dz * dz;
    const double b = ox * dx + oy * dy + oz * dz;
    const double c = ox * ox + oy * oy + oz * oz - 1.0;
    const double disc = b * b - a * c;
    if (disc < 0.0) return kNoHit;
    const double t = (-b - std::sqrt(disc)) / a;
    return t > t_min ? t : kNoHit;
  }

  const SceneParams& p_;
  Vec3 origin_;
  std::vector<TerrainPatch> terrain_;
  std::vector<Box> boxes_;
  std::vector<Cylinder> cylinders_;
  std::vector<Ellipsoid> ellipsoids_;
  std::vector<SectorEntry> sectors_;
};

// The scan pattern: columns of rays sharing an azimuth, rows of elevations.
struct Pattern {
  std::vector<double> azimuth;    // per column [rad]
  std::vector<double> elevation;  // per row [rad]
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

GeneratedScan castPattern(const SceneParams& p, const Scene& scene, const Pattern& pat,
                          bool with_noise) {
  const std::size_t cols = pat.azimuth.size(), rows = pat.elevation.size();
  const std::size_t blocks = std::min(kBlocks, cols);
  std::vector<Block> out(blocks);
  std::vector<double> cos_el(rows), sin_el(rows);
  for (std::size_t r = 0; r < rows; ++r) {
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
    std::mt19937 rng(seq);
    std::normal_distribution<double> range_noise(0.0, sigma > 0.0 ? sigma : 1.0);
    std::normal_distribution<float> intensity_noise(0.0f, 0.03f);
    std::uniform_real_distribution<double> rough_noise(-1.0, 1.0);
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
        const Vec3 d{cos_el[r] * ca, cos_el[r] * sa, sin_el[r]};
        const Hit hit = scene.cast(d, objects, p.min_range, pat.max_range);
        if (hit.t == kNoHit) continue;
        if (!with_noise) {
          blk.truth.push_back(hit.ground ? 1 : 0);
          continue;
        }
        const double range = sigma > 0.0 ? hit.t + range_noise(rng) : hit.t;
        // Grass and dirt: the return comes from a blade or clod up to `roughness` off the surface.
        const double dz = hit.roughness > 0.f ? hit.roughness * rough_noise(rng) : 0.0;
        blk.xyz.push_back(static_cast<float>(d.x * range));
        blk.xyz.push_back(static_cast<float>(d.y * range));
        blk.xyz.push_back(static_cast<float>(d.z * range + dz));
        blk.semantic.push_back(hit.cls);
        blk.intensity.push_back(std::clamp(hit.reflectivity + intensity_noise(rng), 0.0f, 1.0f));
        blk.ring.push_back(static_cast<std::uint16_t>(r));
        blk.truth.push_back(hit.ground ? 1 : 0);
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
      for (const Box& b : boxes) {
        if (x >= b.lo.x && x < b.hi.x && y >= b.lo.y && y < b.hi.y && b.hi.z > z) {
          z = b.hi.z;
          cls = b.cls;
          refl = b.reflectivity;
        }
      }
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

}  // namespace

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
  checkRange("tls_points", static_cast<double>(tls_points), 1000.0, 5e6, "points");
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
}

std::vector<std::string> builtinSceneKinds() {
  return {"lidar", "tls", "verge", "offroad", "trail", "airborne"};
}

SceneParams builtinSceneParams(const std::string& kind) {
  SceneParams params;
  if (kind == "lidar") {
    params.mode = SceneParams::Mode::kLidar64;
  } else if (kind == "tls") {
    params.mode = SceneParams::Mode::kTls;
  } else if (kind == "verge") {
    params.layout = SceneParams::Layout::kVerge;
  } else if (kind == "offroad" || kind == "trail") {
    // Ouster OS1-64 on a small off-road vehicle, as in RELLIS-3D.
    params.layout = kind == "offroad" ? SceneParams::Layout::kOffroad : SceneParams::Layout::kTrail;
    params.uniform_beams = true;
    params.vertical_min_deg = -16.6;
    params.vertical_max_deg = 16.6;
    params.azimuth_steps = 2048;
    params.sensor_height = 1.3;
  } else if (kind == "airborne") {
    params.mode = SceneParams::Mode::kAirborne;
    params.range_noise_sigma = 0.05;
  } else {
    std::string known;
    for (const auto& k : builtinSceneKinds()) known += (known.empty() ? "" : ", ") + k;
    throw std::invalid_argument("unknown built-in scene '" + kind + "' (known: " + known + ")");
  }
  return params;
}

GeneratedScan generateScene(const SceneParams& params) {
  params.validate();
  const Scene scene(params);
  GeneratedScan scan;
  if (params.mode == SceneParams::Mode::kAirborne) {
    scan = airborneScan(params);
  } else if (params.mode == SceneParams::Mode::kLidar64) {
    scan = castPattern(params, scene, lidarPattern(params), true);
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
  insertNans(&scan, params.nan_points);
  return scan;
}

double sceneGroundHeight(const SceneParams& params, double x, double y) {
  const Vec3 o = scannerOrigin(params);
  return worldGroundHeight(params, x + o.x, y + o.y) - o.z;
}

}  // namespace ground_filter
