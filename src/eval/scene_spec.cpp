// builtin:KIND[:SEED][:NAME=VALUE,...] of the tools: the built-in kinds (builtinSceneParams()) and
// their named fields.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "eval/scene_generator.h"  // parseSceneSpec(), sceneOverrideNames()
#include "ground_filter/param_parse.h"

namespace ground_filter {

namespace {

// One field parseSceneSpec() can set: its name and how a text value is stored.
struct SceneOverride {
  const char* name;
  void (*set)(SceneParams* p, const std::string& name, const std::string& value);
};

template <double SceneParams::*kField>
void setDouble(SceneParams* p, const std::string& name, const std::string& value) {
  p->*kField = parseDoubleParam(name, value);
}

template <int SceneParams::*kField>
void setInt(SceneParams* p, const std::string& name, const std::string& value) {
  p->*kField = parseIntParam(name, value);
}

// Counts and seeds: a whole number >= 0 (validate() checks the upper bounds).
template <typename T, T SceneParams::*kField>
void setCount(SceneParams* p, const std::string& name, const std::string& value) {
  const double v = parseDoubleParam(name, value);
  if (v < 0.0 || v != std::floor(v) || v > static_cast<double>(std::numeric_limits<T>::max())) {
    throw std::invalid_argument("parameter '" + name + "': '" + value +
                                "' is not a whole number >= 0");
  }
  p->*kField = static_cast<T>(v);
}

template <bool SceneParams::*kField>
void setBool(SceneParams* p, const std::string& name, const std::string& value) {
  p->*kField = parseBoolParam(name, value);
}

void setLayout(SceneParams* p, const std::string& name, const std::string& value) {
  checkChoice(name.c_str(), value, {"street", "verge", "offroad", "trail", "garage"});
  using L = SceneParams::Layout;
  p->layout = value == "street"    ? L::kStreet
              : value == "verge"   ? L::kVerge
              : value == "offroad" ? L::kOffroad
              : value == "trail"   ? L::kTrail
                                   : L::kGarage;
}

using P = SceneParams;
const SceneOverride kSceneOverrides[] = {
    {"layout", setLayout},
    {"ceiling_height", setDouble<&P::ceiling_height>},
    {"beside_car", setDouble<&P::beside_car>},
    {"sensor_height", setDouble<&P::sensor_height>},
    {"tripod_height", setDouble<&P::tripod_height>},
    {"sensor_x", setDouble<&P::sensor_x>},
    {"sensor_y", setDouble<&P::sensor_y>},
    {"beams", setInt<&P::beams>},
    {"azimuth_steps", setInt<&P::azimuth_steps>},
    {"vertical_min_deg", setDouble<&P::vertical_min_deg>},
    {"vertical_max_deg", setDouble<&P::vertical_max_deg>},
    {"uniform_beams", setBool<&P::uniform_beams>},
    {"lidar_max_range", setDouble<&P::lidar_max_range>},
    {"min_range", setDouble<&P::min_range>},
    {"tls_points", setCount<std::size_t, &P::tls_points>},
    {"tls_min_elevation_deg", setDouble<&P::tls_min_elevation_deg>},
    {"tls_max_elevation_deg", setDouble<&P::tls_max_elevation_deg>},
    {"tls_max_range", setDouble<&P::tls_max_range>},
    {"range_noise_sigma", setDouble<&P::range_noise_sigma>},
    {"grass_roughness", setDouble<&P::grass_roughness>},
    {"nan_points", setCount<std::size_t, &P::nan_points>},
    {"noise_seed", setCount<std::uint32_t, &P::noise_seed>},
    {"airborne_density", setDouble<&P::airborne_density>},
    {"airborne_hall", setDouble<&P::airborne_hall>},
    {"airborne_hall_step", setDouble<&P::airborne_hall_step>},
    {"airborne_hall_gap", setDouble<&P::airborne_hall_gap>},
    {"uav_height", setDouble<&P::uav_height>},
    {"uav_half_angle_deg", setDouble<&P::uav_half_angle_deg>},
    {"uav_line_step", setDouble<&P::uav_line_step>},
    {"uav_angle_step_deg", setDouble<&P::uav_angle_step_deg>},
    {"rosette_fov_deg", setDouble<&P::rosette_fov_deg>},
    {"rosette_rays", setCount<std::size_t, &P::rosette_rays>},
    {"rosette_pitch_deg", setDouble<&P::rosette_pitch_deg>},
    {"slope_x", setDouble<&P::slope_x>},
    {"slope_y", setDouble<&P::slope_y>},
    {"curb_height", setDouble<&P::curb_height>},
    {"ramp_height", setDouble<&P::ramp_height>},
    {"second_returns", setDouble<&P::second_returns>},
    {"positions", setInt<&P::positions>},
    {"position_step", setDouble<&P::position_step>},
    {"position_keep", setDouble<&P::position_keep>},
    {"station_y", setDouble<&P::station_y>},
    {"base_frame", setBool<&P::base_frame>},
    {"mount_roll_deg", setDouble<&P::mount_roll_deg>},
    {"mount_pitch_deg", setDouble<&P::mount_pitch_deg>},
    {"world_frame", setBool<&P::world_frame>},
    {"world_offset_z", setDouble<&P::world_offset_z>},
};

// NAME=VALUE[,NAME=VALUE...] onto *p.
void applySceneOverrides(const std::string& list, SceneParams* p) {
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t comma = std::min(list.find(',', start), list.size());
    const std::string item = list.substr(start, comma - start);
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw std::invalid_argument("scene override '" + item + "' is not NAME=VALUE");
    }
    const std::string name = item.substr(0, eq);
    const SceneOverride* found = nullptr;
    for (const SceneOverride& o : kSceneOverrides) {
      if (name == o.name) found = &o;
    }
    if (!found) {
      std::string known;
      for (const auto& k : sceneOverrideNames()) known += (known.empty() ? "" : ", ") + k;
      throw std::invalid_argument("unknown scene field '" + name + "' (known: " + known + ")");
    }
    found->set(p, name, item.substr(eq + 1));
    start = comma + 1;
  }
}

}  // namespace

std::vector<std::string> sceneOverrideNames() {
  std::vector<std::string> names;
  for (const SceneOverride& o : kSceneOverrides) names.emplace_back(o.name);
  return names;
}

std::vector<std::string> builtinSceneKinds() {
  return {"lidar",    "tls",      "verge",   "offroad", "trail",   "airborne",
          "mls",      "stations", "slam",    "tls_far", "mls_air", "uav",
          "corridor", "lidar16",  "rosette", "garage",  "profiler"};
}

namespace {

// A spinning LiDAR with `beams` evenly over +-half_fov_deg, `steps` firings a turn, `height` m up.
void evenBeams(SceneParams* p, int beams, double half_fov_deg, int steps, double height) {
  p->beams = beams;
  p->uniform_beams = true;
  p->vertical_min_deg = -half_fov_deg;
  p->vertical_max_deg = half_fov_deg;
  p->azimuth_steps = steps;
  p->sensor_height = height;
}

}  // namespace

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
    evenBeams(&params, 64, 16.6, 2048, 1.3);
  } else if (kind == "lidar16") {
    // A small robot's 16-beam sensor (VLP-16: +-15 deg, 2 deg between beams, 0.2 deg a firing),
    // 0.7 m above the street: rings ten firings apart.
    evenBeams(&params, 16, 15.0, 1800, 0.7);
    params.lidar_max_range = 100.0;
  } else if (kind == "airborne" || kind == "corridor") {
    params.mode = SceneParams::Mode::kAirborne;
    params.range_noise_sigma = 0.05;
    if (kind == "corridor") {  // a 30 m wide strip of the tile: a corridor survey's footprint
      params.world_frame = true;
      params.crop_half_width = 15.0;
    }
  } else if (kind == "mls" || kind == "mls_air") {
    params.positions = 21;  // 80 m of street, a sweep every 4 m, a quarter of each kept
    params.position_keep = 0.25;
    params.world_frame = true;
    if (kind == "mls_air") params.airborne_extra = 0.03;
  } else if (kind == "stations" || kind == "tls_far") {
    params.mode = SceneParams::Mode::kTls;
    params.world_frame = true;
    if (kind == "stations") {
      params.positions = 3;
      params.position_step = 30.0;
      params.station_y = 2.5;
      params.tls_points = 300000;
    } else {  // one station exported in map coordinates
      params.tls_points = 500000;
      params.world_offset_x = 2400.0;
      params.world_offset_y = -1700.0;
      params.world_offset_z = 310.0;
    }
  } else if (kind == "slam") {  // an off-road robot's map tile: OS1-64 sweeps along the trail
    params.layout = SceneParams::Layout::kTrail;
    evenBeams(&params, 64, 16.6, 2048, 1.3);
    params.positions = 31;
    params.position_step = 2.0;
    params.position_keep = 0.2;
    params.follow_track = true;
    params.world_frame = true;
    params.crop_half_width = 30.0;
    params.crop_half_length = 30.0;
  } else if (kind == "rosette") {
    // A small robot's solid-state sensor (Livox Avia / Mid-70 class: a 70 deg disc, 240 k
    // returns a second, 0.1 s frames) 0.7 m above the street, looking along it.
    params.mode = SceneParams::Mode::kRosette;
    params.sensor_height = 0.7;
    params.lidar_max_range = 100.0;
  } else if (kind == "garage") {
    // A car's 128-beam sensor (OS1-128: +-22.5 deg) 1.8 m up on a parking level: the ceiling,
    // 0.8 m above the sensor, is a larger and denser flat surface than the floor it sees.
    params.layout = SceneParams::Layout::kGarage;
    evenBeams(&params, 128, 22.5, 2048, 1.8);
  } else if (kind == "uav" || kind == "profiler") {
    params.mode = SceneParams::Mode::kUav;
    params.world_frame = true;
    params.crop_half_length = 80.0;
    if (kind == "profiler") {
      // A mobile-mapping van's profile scanner (Riegl VMX class): its rays turn in the plane
      // across the track, 2.5 m up in the right lane; a profile every 0.1 m along 80 m of street.
      // Each profile sees the road at its feet and the facades beside it: density does not
      // fall with range from one position, nor is it the even sampling of a nadir view.
      params.uav_height = 2.5;
      params.uav_half_angle_deg = 180.0;
      params.uav_line_step = 0.1;
      params.sensor_y = -2.0;
      params.crop_half_length = 40.0;
    }
  } else {
    std::string known;
    for (const auto& k : builtinSceneKinds()) known += (known.empty() ? "" : ", ") + k;
    throw std::invalid_argument("unknown built-in scene '" + kind + "' (known: " + known + ")");
  }
  return params;
}

SceneParams parseSceneSpec(const std::string& spec) {
  const std::size_t colon = spec.find(':');
  SceneParams params = builtinSceneParams(spec.substr(0, colon));
  if (colon == std::string::npos) return params;
  std::string rest = spec.substr(colon + 1);
  const std::size_t next = rest.find(':');
  const std::string seed = rest.substr(0, next);
  if (seed.find('=') == std::string::npos) {  // KIND:SEED[:FIELDS]
    char* end = nullptr;
    const unsigned long long v = std::strtoull(seed.c_str(), &end, 10);
    if (seed.empty() || !std::isdigit(static_cast<unsigned char>(seed[0])) || *end != '\0' ||
        v > 0xFFFFFFFFull) {
      throw std::invalid_argument("seed '" + seed + "' is not an unsigned 32-bit integer");
    }
    params.seed = static_cast<std::uint32_t>(v);
    if (next == std::string::npos) return params;
    rest = rest.substr(next + 1);
  }
  applySceneOverrides(rest, &params);
  return params;
}

}  // namespace ground_filter
