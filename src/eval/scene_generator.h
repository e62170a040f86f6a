#ifndef GROUND_FILTER_SRC_EVAL_SCENE_GENERATOR_H
#define GROUND_FILTER_SRC_EVAL_SCENE_GENERATOR_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ground_filter {

/// \brief Parameters of the procedural street scene and of the simulated scanner. One line per
///        field: meaning [unit] (default).
///
/// World (`layout`): kStreet is a road along +x with a gentle slope, a curb up to a sidewalk at
/// y = curb_y, a ramp joining two terrain levels (ramp_start_x .. ramp_end_x), buildings, cars,
/// poles and trees whose canopies overhang the ground. The other layouts reproduce failure modes
/// of real scans (README, "Generated scenes"): grass verges and lawns sloping beside a road,
/// rolling off-road grassland with bushes and undergrowth, a hilly dirt trail. The terrain (road,
/// curb face, sidewalk, ramp, grass, dirt) is ground; everything else (bushes and undergrowth of
/// any height included) is not. The layout of objects depends on `seed` only; the range noise
/// on `seed` and `noise_seed`; the scanner position on `sensor_x`.
struct SceneParams {
  /// \brief Scanner model.
  enum class Mode {
    kLidar64,   ///< spinning 64-beam LiDAR on a car (HDL-64-like), ~100 k returns
    kTls,       ///< terrestrial laser scanner on a tripod: dense spherical sweep, 1-100 M returns
    kAirborne,  ///< nadir airborne scan of its own hilly world with buildings, trees, bushes and
                ///< cars (layout ignored): airborne_density points per m2, world frame
    kRosette,   ///< solid-state sensor looking along +x, sensor_height up, non-repetitive
                ///< rosette pattern (two counter-rotating prisms, Livox-like)
    kUav,       ///< line scanner moving along world x over the layout, uav_height up, rays
                ///< across the track within +-uav_half_angle_deg of nadir (a UAV; with 180 deg
                ///< a van's profile scanner), world frame
  };
  /// \brief World layout.
  enum class Layout {
    kStreet,   ///< road, curb, sidewalk, ramp, buildings, cars, poles, trees
    kVerge,    ///< road with a grass verge sloping away on one side and a kerb, sidewalk and a
               ///< lawn rising away on the other; bushes, trees, cars, poles
    kOffroad,  ///< rolling grassland with a dirt track, bushes 0.3-1 m, undergrowth, trees
    kTrail,    ///< hilly terrain (slopes up to ~25 %) with a winding dirt trail, grass, bushes
    kGarage,   ///< a parking level: flat concrete floor, a ceiling ceiling_height above it over
               ///< the whole 60 m x 40 m level, walls, pillars on an 8 m grid, parked cars
  };
  Mode mode = Mode::kLidar64;       ///< scanner model (kLidar64)
  Layout layout = Layout::kStreet;  ///< world layout (kStreet)
  std::uint32_t seed = 1;           ///< layout (and noise) seed [-] (1)
  std::uint32_t noise_seed = 0;     ///< extra seed of the noise only, e.g. scan index [-] (0)

  // Scanner pose. Output points are in the scanner frame: x forward (along the road), z up.
  double sensor_x = 0.0;  ///< scanner position along the road (world x) [m] (0)
  double sensor_y = 0.0;  ///< scanner lateral position (world y; road spans -6..curb_y) [m] (0)
  double sensor_height = 1.73;  ///< LiDAR height above the ground below it [m] (1.73)
  double tripod_height = 1.5;   ///< TLS height above the ground below it [m] (1.5)

  // Spinning LiDAR (kLidar64).
  int beams = 64;                   ///< lasers (rings) [-] (64)
  int azimuth_steps = 1800;         ///< firings per revolution [-] (1800, i.e. 0.2 deg)
  double vertical_min_deg = -24.8;  ///< lowest beam elevation [deg] (-24.8)
  double vertical_max_deg = 2.0;    ///< highest beam elevation [deg] (2.0)
  double lidar_max_range = 80.0;    ///< farther hits give no return [m] (80)
  double min_range = 1.0;           ///< nearer hits give no return (own vehicle/tripod) [m] (1.0)
  bool uniform_beams = false;  ///< beams evenly spread (Ouster) instead of HDL-64's split (false)

  // Terrestrial scanner (kTls).
  std::size_t tls_points = 2000000;  ///< point budget, never exceeded [points] (2 M; 1 k..100 M)
  double tls_min_elevation_deg = -60.0;  ///< lowest ray elevation [deg] (-60)
  double tls_max_elevation_deg = 60.0;   ///< highest ray elevation [deg] (60)
  double tls_max_range = 120.0;          ///< farther hits give no return [m] (120)

  // Sensor model.
  double range_noise_sigma = 0.02;  ///< Gaussian range noise, standard deviation [m] (0.02)
  std::size_t nan_points = 0;       ///< NaN points inserted for robustness demos [points] (0)
  /// Half-range of the uniform vertical noise of grass returns (blades, tufts) [m] (0.05);
  /// dirt gets a fifth of it, roads and sidewalks none. Only the non-street layouts have grass.
  double grass_roughness = 0.05;
  double airborne_density = 1.5;  ///< kAirborne: pulses per m2 over the tile [points/m2] (1.5)
  /// kAirborne: edge of one more flat-roofed hall, square, at the tile's centre, its roof 8 m
  /// above the highest terrain under it [m] (0: none): wider than the airborne mode's opening
  /// (2 x morph_window) from 36 m.
  double airborne_hall = 0.0;
  /// kAirborne: the hall's roof in thirds along x at several heights: the west third this much
  /// lower, the centre this much higher (a raised bay), the east third as without it [m] (0:
  /// one flat roof; at most 6).
  double airborne_hall_step = 0.0;
  /// kAirborne: a strip this wide across the hall's roof (along y, at its centre) returns no
  /// pulse (a dark membrane, glass, a gap between flight lines) [m] (0: none; at most 40).
  double airborne_hall_gap = 0.0;
  double uav_height = 40.0;  ///< kUav: flying height over the ground below it [m] (40)
  /// kUav: half the across-track field of view [deg] (35; 1..180, 180: every direction of
  /// the plane across the track, a profile scanner)
  double uav_half_angle_deg = 35.0;
  double uav_line_step = 0.25;       ///< kUav: flight distance between scan lines [m] (0.25)
  double uav_angle_step_deg = 0.25;  ///< kUav: angle between rays of a line [deg] (0.25)
  double rosette_fov_deg = 70.4;     ///< kRosette: circular field of view, full angle [deg] (70.4)
  std::size_t rosette_rays =
      24000;                       ///< kRosette: rays of one frame (240 k/s x 0.1 s) [rays] (24 k)
  double rosette_pitch_deg = 0.0;  ///< kRosette: optical axis pitch, < 0 down [deg] (0)

  // Registered clouds: several scanner positions merged in one world frame, as a mobile-mapping
  // run, several TLS stations or a SLAM map tile give them (no sensor at the origin).
  int positions = 1;           ///< scanner positions merged; 1: one scan [-] (1)
  double position_step = 4.0;  ///< distance between positions along world x [m] (4)
  double position_keep = 1.0;  ///< share of each position's points kept, evenly [-] (1)
  bool follow_track = false;   ///< positions follow the trail's centre line (y) [-] (false)
  double station_y = 0.0;      ///< positions alternate between y = +-station_y [m] (0)
  bool world_frame = false;    ///< points in the world frame (+ world_offset), not the scanner's
  /// One scan in a frame on the ground right below its scanner, z up (a robot's base_link or
  /// base_footprint): the scanner frame moved down by the scanner's height [-] (false).
  bool base_frame = false;
  /// A scanner mounted tilted, with no gravity frame to undo it: the points of the level scan
  /// expressed in a frame rolled about the scanner's x axis by this angle [deg] (0; -90..90:
  /// beyond the levelling's 60 deg too, to test it).
  /// One scan in its own (or base) frame only.
  double mount_roll_deg = 0.0;
  /// ... and then pitched about its y axis, right-handed (> 0 tips x down, REP 103) [deg] (0;
  /// -90..90).
  double mount_pitch_deg = 0.0;
  double world_offset_x = 0.0;    ///< added to every x of a world-frame cloud [m] (0)
  double world_offset_y = 0.0;    ///< added to every y of a world-frame cloud [m] (0)
  double world_offset_z = 0.0;    ///< added to every z of a world-frame cloud [m] (0)
  double crop_half_width = 0.0;   ///< world frame: keep |y| <= this (0: no crop) [m] (0)
  double crop_half_length = 0.0;  ///< world frame: keep |x| <= this (0: no crop) [m] (0)
  /// Share of extra returns from a nadir UAV pass over the same world (uav_* fields, a 10 deg
  /// half angle) added to a registered cloud [-] (0): a map with a few airborne returns.
  double airborne_extra = 0.0;
  /// Dual-return sensor: share of the beams whose first echo is foliage (bushes, undergrowth,
  /// tree crowns) that also return the next surface 1 m or more behind it, as a second point
  /// right after the first [-] (0; 0 .. 1). Those points lie behind nearer ones seen from the
  /// sensor, as in a merged cloud.
  double second_returns = 0.0;

  // Terrain (world frame; road level z = slope_x * x + slope_y * y + ramp).
  double slope_x = 0.02;        ///< road slope along x (gentle) [m/m] (0.02)
  double slope_y = 0.01;        ///< cross slope along y [m/m] (0.01)
  double curb_y = 6.0;          ///< curb line; sidewalk for y >= curb_y [m] (6.0)
  double curb_height = 0.15;    ///< curb step up to the sidewalk [m] (0.15)
  double ramp_start_x = 18.0;   ///< ramp foot (lower level ends) [m] (18)
  double ramp_end_x = 33.0;     ///< ramp top (upper level starts) [m] (33)
  double ramp_height = 2.0;     ///< upper level minus lower level [m] (2.0)
  double scene_extent = 90.0;   ///< objects are placed for |world x| <= this [m] (90)
  double ceiling_height = 2.6;  ///< kGarage: the ceiling's underside above the floor [m] (2.6)
  /// kStreet: a car in the next lane beside the scanner, its centre this far to the side (world
  /// y = sensor_y - beside_car, x = sensor_x); 0 = none; the rest of the layout unchanged [m] (0)
  double beside_car = 0.0;

  /// \brief Checks every field's range.
  /// \throws std::invalid_argument naming the first bad field, its value and its range.
  void validate() const;
};

/// \brief SemanticKITTI class ids the generator writes to GeneratedScan::semantic.
enum SceneClass : std::uint16_t {
  kClassUnlabelled = 0,    ///< NaN points
  kClassCar = 10,          ///< car bodies and cabins
  kClassRoad = 40,         ///< road (asphalt)
  kClassSidewalk = 48,     ///< sidewalk and curb face
  kClassOtherGround = 49,  ///< dirt track or trail
  kClassBuilding = 50,     ///< buildings
  kClassVegetation = 70,   ///< tree crowns, bushes, undergrowth (never ground in the truth)
  kClassTrunk = 71,        ///< tree trunks
  kClassTerrain = 72,      ///< grass verges, lawns, grassland (ground, rough)
  kClassPole = 80,         ///< poles
};

/// \brief A generated scan: per-point arrays in scanner order (azimuth column, then elevation).
struct GeneratedScan {
  std::vector<float> xyz;           ///< packed x y z [m], scanner frame
  std::vector<float> intensity;     ///< reflectivity-like value [0, 1]
  std::vector<std::uint16_t> ring;  ///< beam index (LiDAR) or elevation row (TLS)
  std::vector<std::uint8_t> truth;  ///< 1 ground, 0 non-ground (NaN points are 0)
  /// SemanticKITTI class of each point (kClass* below; NaN points kClassUnlabelled).
  std::vector<std::uint16_t> semantic;
  /// \brief Number of points.
  std::size_t size() const { return truth.size(); }
};

/// \brief Scene and scanner of a named built-in scene (`builtin:KIND[:SEED]` of the tools):
///        `lidar` (street, HDL-64), `tls` (street, tripod scanner), `verge` (grass verge and
///        sloped lawns beside a road, HDL-64), `offroad` (grassland with bushes and undergrowth,
///        Ouster OS1-64 1.3 m up), `trail` (hilly dirt trail, Ouster OS1-64 1.3 m up),
///        `airborne` (nadir scan, 1.5 points/m2, of a 180 m tile with hills, an embankment,
///        buildings, trees, bushes and cars; 5 cm height noise). Registered clouds in a world
///        frame (no sensor at the origin): `mls` (HDL-64 sweeps every 4 m along the street,
///        merged), `stations` (three TLS stations 30 m apart), `slam` (OS1-64 sweeps every 2 m
///        along the trail, a 60 m map tile), `tls_far` (one TLS station 2.4 km from the origin),
///        `mls_air` (`mls` plus 3 % returns of a nadir UAV pass); nadir clouds of the same kind of
///        world: `uav` (a line scanner 40 m up flying along the street, +-35 deg),
///        `corridor` (the airborne tile cut to a 30 m wide strip); `lidar16` (the street seen by a
///        small robot's 16-beam sensor, VLP-16-like, 0.7 m up: scan lines far apart);
///        `rosette` (the street seen by a solid-state sensor 0.7 m up, Livox-like: a 70.4 deg
///        forward disc of 24 k non-repeating rays); `garage` (a parking level under its
///        ceiling); `profiler` (a mobile-mapping van's profile scanner 2.5 m up: one profile
///        across the track every 0.1 m along 80 m of street, registered in the world frame).
/// \throws std::invalid_argument naming the known kinds for any other name.
SceneParams builtinSceneParams(const std::string& kind);

/// \brief The kinds builtinSceneParams() knows, in the order above.
std::vector<std::string> builtinSceneKinds();

/// \brief The scene of a `builtin:` spec without its prefix, `KIND[:SEED][:NAME=VALUE,...]`:
///        builtinSceneParams(KIND) with the layout seed and then the named fields set, e.g.
///        `lidar16:2:layout=trail,sensor_height=1.2,beams=32` (a 32-beam sensor 1.2 m above the
///        trail). NAME is one of sceneOverrideNames(); `layout` takes street, verge, offroad or
///        trail, `uniform_beams` a boolean, the others numbers. Ranges are checked by
///        generateScene() (SceneParams::validate()).
/// \throws std::invalid_argument naming the unknown kind, the bad seed, the unknown field (with
///         the known ones) or the bad value.
SceneParams parseSceneSpec(const std::string& spec);

/// \brief The fields parseSceneSpec() can set, in a fixed order.
std::vector<std::string> sceneOverrideNames();

/// \brief Ray-casts the procedural scene with the scanner of `params.mode`.
///
/// Deterministic for given params (independent of the number of OpenMP threads). Rays that hit
/// nothing within range produce no point.
/// \throws std::invalid_argument when params.validate() fails.
GeneratedScan generateScene(const SceneParams& params);

/// \brief True when generateScene() gives `params`' points in the world frame (registered
///        clouds, kUav) rather than the scanner frame.
bool sceneInWorldFrame(const SceneParams& params);

/// \brief Height of the terrain surface below (x, y) of the output frame of `params` (the
///        scanner frame, or the world frame plus world_offset), in that frame [m]: the exact
///        surface the ground points were sampled from, before range noise and grass roughness
///        (kStreet: the sidewalk level from the curb line on, i.e. world y >= curb_y). NaN for
///        a tilted mount (mount_roll_deg, mount_pitch_deg): that frame's z is not vertical.
double sceneGroundHeight(const SceneParams& params, double x, double y);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_EVAL_SCENE_GENERATOR_H
