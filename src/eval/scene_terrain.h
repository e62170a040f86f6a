// Private to the scene generator: shapes, materials and the terrain height functions of the
// generated scenes (scene_terrain.cpp), shared by the scene (scene_world.h) and the scan
// patterns (scene_generator.cpp).
#ifndef GROUND_FILTER_SRC_EVAL_SCENE_TERRAIN_H
#define GROUND_FILTER_SRC_EVAL_SCENE_TERRAIN_H

#include <cstdint>
#include <limits>

#include "eval/scene_generator.h"

namespace ground_filter {
namespace scene {

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

// kVerge: road |y| <= 4 with 2 % camber; y > 4 a grass verge falling away at 17-33 % for
// 3.5 m, then a lawn rising at 6 %; y < -4 a 0.12 m kerb, a 2 m sidewalk and a lawn rising at
// 13-23 % for 8 m, then level.
constexpr double kVergeRoadHalfWidth = 4.0;
constexpr double kVergeSidewalkEnd = -6.0;
constexpr double kTrackHalfWidth = 1.3;

double rampOffset(const SceneParams& p, double x);
double roadHeight(const SceneParams& p, double x, double y);
// A per-seed phase in [0, 2 pi) for term k of the natural terrains (splitmix64 of seed and k).
double phase(const SceneParams& p, std::uint64_t k);
double vergeHeight(const SceneParams& p, double x, double y);
// kOffroad: rolling grassland, slopes mostly under 20 %.
double offroadHeight(const SceneParams& p, double x, double y);
// Centre line of the dirt track (kOffroad) or trail (kTrail), through y = 0 at x = 0.
double trackCentre(const SceneParams& p, double x);
// kTrail: hills of a few metres, slopes up to about 25 %.
double trailHeight(const SceneParams& p, double x, double y);
// kAirborne: hills of several metres (slopes up to ~30 %) and an embankment that rises 5 m
// over 9 m (about 55 %) along a line across the tile.
double airborneHeight(const SceneParams& p, double x, double y);
double worldGroundHeight(const SceneParams& p, double x, double y);
/// The frame of a scanner mounted tilted by R = Ry(mount_pitch_deg) Rx(mount_roll_deg): each of
/// the n packed points p becomes R^T p (nothing where both angles are 0).
void turnToMount(const SceneParams& p, float* xyz, std::size_t n);
// Surface class of the non-street terrains at (x, y) (world frame).
std::uint16_t naturalClass(const SceneParams& p, double x, double y);
Vec3 scannerOrigin(const SceneParams& p);
// Lowest / highest terrain height over a footprint, sampled at (steps + 1)^2 points (terrain is
// piecewise linear: a 5x5 sample with the corners is exact enough to bury object bottoms).
double minGroundOver(const SceneParams& p, double x0, double x1, double y0, double y1,
                     int steps = 4);
double maxGroundOver(const SceneParams& p, double x0, double x1, double y0, double y1,
                     int steps = 4);
// The airborne tile's hall (SceneParams::airborne_hall): its roof 8 m above the highest terrain
// under it, in three parts at several heights where airborne_hall_step is set; its boxes onto
// *boxes.
void airborneHall(const SceneParams& p, std::vector<Box>* boxes);

}  // namespace scene
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_EVAL_SCENE_TERRAIN_H
