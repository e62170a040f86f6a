#include "eval/scene_terrain.h"

#include <algorithm>
#include <cmath>

namespace ground_filter {
namespace scene {

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
    case SceneParams::Layout::kGarage:
      return 0.0;  // a flat concrete floor
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
  const double h = p.mode == SceneParams::Mode::kTls   ? p.tripod_height
                   : p.mode == SceneParams::Mode::kUav ? p.uav_height
                                                       : p.sensor_height;
  return {p.sensor_x, p.sensor_y, worldGroundHeight(p, p.sensor_x, p.sensor_y) + h};
}

namespace {
// The terrain heights at (steps + 1)^2 points of a footprint, folded by `pick` from `start`.
template <class Pick>
double groundOver(const SceneParams& p, double x0, double x1, double y0, double y1, int steps,
                  double start, Pick pick) {
  double m = start;
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; j <= steps; ++j) {
      m = pick(m, worldGroundHeight(p, x0 + (x1 - x0) * i / steps, y0 + (y1 - y0) * j / steps));
    }
  }
  return m;
}
}  // namespace

double minGroundOver(const SceneParams& p, double x0, double x1, double y0, double y1, int steps) {
  return groundOver(p, x0, x1, y0, y1, steps, kNoHit,
                    [](double a, double b) { return std::min(a, b); });
}
double maxGroundOver(const SceneParams& p, double x0, double x1, double y0, double y1, int steps) {
  return groundOver(p, x0, x1, y0, y1, steps, -kNoHit,
                    [](double a, double b) { return std::max(a, b); });
}
void airborneHall(const SceneParams& p, std::vector<Box>* boxes) {
  const double h = 0.5 * std::min(p.airborne_hall, 1.6 * p.scene_extent);
  const double top = maxGroundOver(p, -h, h, -h, h, 20) + 8.0;  // on a levelled pad
  const double base = minGroundOver(p, -h, h, -h, h) - 1.0;
  // Thirds along x: the west one airborne_hall_step lower, the centre as much higher (a raised
  // bay), the east one at `top`; one flat roof where the step is 0.
  const double s = p.airborne_hall_step, x1 = -h / 3.0, x2 = h / 3.0;
  boxes->push_back({{-h, -h, base}, {x1, h, top - s}, kWallReflectivity, kClassBuilding});
  boxes->push_back({{x1, -h, base}, {x2, h, top + s}, kWallReflectivity, kClassBuilding});
  boxes->push_back({{x2, -h, base}, {h, h, top}, kWallReflectivity, kClassBuilding});
}
void turnToMount(const SceneParams& p, float* xyz, std::size_t n) {
  if (p.mount_roll_deg == 0.0 && p.mount_pitch_deg == 0.0) return;
  const double deg = 3.14159265358979323846 / 180.0;
  const double cr = std::cos(p.mount_roll_deg * deg), sr = std::sin(p.mount_roll_deg * deg);
  const double cp = std::cos(p.mount_pitch_deg * deg), sp = std::sin(p.mount_pitch_deg * deg);
  for (std::size_t i = 0; i < n; ++i) {
    float* q = xyz + 3 * i;
    const double x = q[0], y = q[1], z = q[2];
    const double xa = cp * x - sp * z, za = sp * x + cp * z;  // Ry(pitch)^T
    q[0] = static_cast<float>(xa);
    q[1] = static_cast<float>(cr * y + sr * za);  // then Rx(roll)^T
    q[2] = static_cast<float>(-sr * y + cr * za);
  }
}

}  // namespace scene
}  // namespace ground_filter
