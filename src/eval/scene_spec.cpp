// builtin:KIND[:SEED][:NAME=VALUE,...] of the tools: a built-in scene with named fields set.
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
    {"uav_height", setDouble<&P::uav_height>},
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
