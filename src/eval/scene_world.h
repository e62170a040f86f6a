// Private to the scene generator: the objects and terrain of a generated scene and the ray cast
// against them (scene_generator.cpp casts the scan patterns).
#ifndef GROUND_FILTER_SRC_EVAL_SCENE_WORLD_H
#define GROUND_FILTER_SRC_EVAL_SCENE_WORLD_H

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "eval/scene_generator.h"
#include "eval/scene_terrain.h"

namespace ground_filter {
namespace scene {

class Scene {
 public:
  explicit Scene(const SceneParams& p) : p_(p), origin_(scannerOrigin(p)) {
    if (p.layout == SceneParams::Layout::kStreet) {
      buildTerrain();
      buildLayout();
    } else if (p.layout == SceneParams::Layout::kGarage) {
      buildGarage();
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
    if (p_.layout != SceneParams::Layout::kStreet && p_.layout != SceneParams::Layout::kGarage) {
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

    // A car beside the scanner (beside_car): its own random stream, so nothing else moves.
    if (p_.beside_car > 0.0) {
      std::mt19937 car_rng(p_.seed ^ 0x5bd1e995u);
      addCar(car_rng, p_.sensor_x, p_.sensor_y - p_.beside_car);
    }
  }

  // A parking level: the floor (one flat patch), a ceiling slab over the whole level, outer walls,
  // pillars on an 8 m grid and rows of parked cars, none within 3 m of the scanner.
  void buildGarage() {
    const double inf = std::numeric_limits<double>::infinity();
    terrain_.push_back({0.0, 0.0, 0.0, -inf, inf, -inf, inf, kRoadReflectivity, kClassRoad});
    const double hx = 30.0, hy = 20.0, top = p_.ceiling_height, wall = 0.3;
    addBox(-hx, hx, -hy, hy, top, top + 0.3, kWallReflectivity, kClassBuilding);
    addBox(-hx - wall, -hx, -hy, hy, -0.5, top, kWallReflectivity, kClassBuilding);
    addBox(hx, hx + wall, -hy, hy, -0.5, top, kWallReflectivity, kClassBuilding);
    addBox(-hx, hx, -hy - wall, -hy, -0.5, top, kWallReflectivity, kClassBuilding);
    addBox(-hx, hx, hy, hy + wall, -0.5, top, kWallReflectivity, kClassBuilding);
    auto clear = [&](double x, double y, double r) {
      return std::hypot(x - p_.sensor_x, y - p_.sensor_y) >= r;
    };
    for (double x = -hx + 4.0; x < hx; x += 8.0) {
      for (double y = -hy + 4.0; y < hy; y += 8.0) {
        if (clear(x, y, 1.5))
          addBox(x - 0.25, x + 0.25, y - 0.25, y + 0.25, -0.5, top, kWallReflectivity,
                 kClassBuilding);
      }
    }
    std::mt19937 rng(p_.seed);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    for (double y : {-16.0, -8.5, 8.5, 16.0}) {  // two aisles, cars parked on both sides of each
      for (double x = -hx + 3.0; x < hx - 3.0; x += 5.2) {
        if (u01(rng) < 0.65 && clear(x, y, 3.0)) addCar(rng, x, y);
      }
    }
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

}  // namespace scene
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_EVAL_SCENE_WORLD_H
