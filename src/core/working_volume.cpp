#include "ground_filter/working_volume.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/threads_timing.h"
#include "ground_filter/param_parse.h"
#include "ground_filter/point_field.h"

namespace ground_filter {

namespace {

// The finite points of `cloud` outside `volume` (its ball and box; exclusions not counted).
std::size_t finiteOutside(const CloudView& cloud, const WorkingVolume& volume) {
  std::size_t outside = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    float x, y, z;
    if (cloud.get(i, &x, &y, &z) && !volume.contains(x, y, z)) ++outside;
  }
  return outside;
}

// Whether more than half of the `finite` points of `cloud` lie beyond the hard box around
// `volume`'s origin (its ball left out).
bool mostBeyondBox(const CloudView& cloud, const WorkingVolume& volume, std::size_t finite) {
  WorkingVolume box = volume;
  box.max_range = 0.0;
  return finiteOutside(cloud, box) * 2 > finite;
}

}  // namespace

void WorkingVolume::validate() const {
  if (!(max_range == 0.0 || (max_range > 0.0 && max_range <= kWorkingVolumeHardLimit))) {
    throw std::invalid_argument("max_range = " + std::to_string(max_range) +
                                " m is outside 0 (off) or (0, " +
                                std::to_string(kWorkingVolumeHardLimit) + "] m");
  }
  if (!(min_range >= 0.0 && min_range <= kWorkingVolumeHardLimit)) {
    throw std::invalid_argument("min_range = " + std::to_string(min_range) + " m is outside [0, " +
                                std::to_string(kWorkingVolumeHardLimit) + "] m");
  }
  if (max_range > 0.0 && min_range >= max_range) {
    throw std::invalid_argument("min_range = " + std::to_string(min_range) +
                                " m is not below max_range = " + std::to_string(max_range) +
                                " m (nothing would be filtered)");
  }
  if (!body_box.empty()) {
    if (body_box.size() != 6) {
      throw std::invalid_argument("body_box has " + std::to_string(body_box.size()) +
                                  " values, expected 6: [xmin, xmax, ymin, ymax, zmin, zmax] m");
    }
    static const char* const kAxis[] = {"x", "y", "z"};
    for (int d = 0; d < 3; ++d) {
      const double lo = body_box[2 * d], hi = body_box[2 * d + 1];
      if (!std::isfinite(lo) || !std::isfinite(hi)) {
        throw std::invalid_argument(std::string("body_box ") + kAxis[d] + " bounds are not finite");
      }
      if (lo > hi) {
        throw std::invalid_argument(std::string("body_box ") + kAxis[d] +
                                    "min = " + std::to_string(lo) + " m is above " + kAxis[d] +
                                    "max = " + std::to_string(hi) + " m");
      }
    }
  }
  for (float o : origin) {
    if (!std::isfinite(o)) throw std::invalid_argument("working volume origin is not finite");
  }
  for (float r : rotation) {
    if (!std::isfinite(r)) throw std::invalid_argument("working volume rotation is not finite");
  }
}

std::vector<double> parseBodyBox(const std::string& key, const std::string& value) {
  std::string s = value;
  for (char& c : s) {
    if (c == '[' || c == ']' || c == ',') c = ' ';
  }
  std::istringstream in(s);
  std::vector<double> box;
  std::string word;
  while (in >> word) box.push_back(parseDoubleParam(key, word));
  if (!box.empty() && box.size() != 6) {
    throw std::invalid_argument(key + " = '" + value + "' has " + std::to_string(box.size()) +
                                " values, expected 6: [xmin, xmax, ymin, ymax, zmin, zmax] m");
  }
  return box;
}

WorkingVolumeFilter::WorkingVolumeFilter(std::unique_ptr<GroundFilter> inner,
                                         const WorkingVolume& volume)
    : inner_(std::move(inner)), volume_(volume) {
  if (!inner_) throw std::invalid_argument("WorkingVolumeFilter needs an inner filter");
  volume_.validate();
  inner_->setSensorOrigin(volume_.origin[0], volume_.origin[1], volume_.origin[2]);
}

void WorkingVolumeFilter::setOrigin(float x, float y, float z) {
  WorkingVolume v = volume_;
  v.origin[0] = x;
  v.origin[1] = y;
  v.origin[2] = z;
  v.validate();
  volume_ = v;
  inner_->setSensorOrigin(x, y, z);
}

void WorkingVolumeFilter::setPose(const float origin[3], const float rotation[9]) {
  WorkingVolume v = volume_;
  for (int i = 0; i < 3; ++i) v.origin[i] = origin[i];
  for (int i = 0; i < 9; ++i) v.rotation[i] = rotation[i];
  v.validate();
  volume_ = v;
  inner_->setSensorOrigin(origin[0], origin[1], origin[2]);  // as setOrigin(): one sensor origin
}

bool WorkingVolumeFilter::recentre(const CloudView& cloud, std::size_t* out_of_range,
                                   WorkingVolume* volume, float shift[3]) {
  // trimmedMiddle() of an even sample.
  const std::size_t n = cloud.size();
  const std::size_t step = std::max<std::size_t>(1, n / kRecentreSamples);
  for (int d = 0; d < 3; ++d) {
    axis_.clear();
    for (std::size_t i = 0; i < n; i += step) {
      float p[3];
      if (cloud.get(i, &p[0], &p[1], &p[2])) axis_.push_back(p[d]);
    }
    if (axis_.empty()) return false;
    shift[d] = static_cast<float>(trimmedMiddle(&axis_));
  }
  WorkingVolume moved = *volume;
  for (int d = 0; d < 3; ++d) moved.origin[d] = shift[d];
  // The sensor's surroundings lie kilometres from such a cloud: nothing of it is excluded.
  moved.min_range = 0.0;
  moved.body_box.clear();
  const std::size_t outside = finiteOutside(cloud, moved);
  if (outside >= *out_of_range) {  // the box holds no more of the cloud there: keep it as it was
    std::fill_n(shift, 3, 0.f);
    return false;
  }
  *volume = moved;
  *out_of_range = outside;
  return true;
}

void WorkingVolumeFilter::filterPacked(const float* shift, FilterStats* inner_stats) {
  const CloudView packed = CloudView::packedXyz(xyz_.data(), kept_.size());
  if (!shift) {
    inner_->filter(packed, &inner_labels_, inner_stats);
    return;
  }
  const float* o = volume_.origin;
  inner_->setSensorOrigin(o[0] - shift[0], o[1] - shift[1], o[2] - shift[2]);
  try {
    inner_->filter(packed, &inner_labels_, inner_stats);
  } catch (...) {
    inner_->setSensorOrigin(o[0], o[1], o[2]);
    throw;
  }
  inner_->setSensorOrigin(o[0], o[1], o[2]);
  char text[160];
  std::snprintf(text, sizeof(text),
                "; the working volume's +-%.0f m box moved onto the cloud's middle (%.0f %.0f "
                "%.0f): no point lies near the origin",
                kWorkingVolumeHardLimit, shift[0] + 0.0, shift[1] + 0.0, shift[2] + 0.0);
  inner_stats->scan_reason += text;
}

void WorkingVolumeFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                                 FilterStats* stats) {
  const auto t0 = Clock::now();
  const std::size_t n = cloud.size();
  // The usual case: the inner filter tests the volume on its way, no pass here. Not asked again
  // after it declined until the wrapper's own pass finds every point inside (a stream of scans
  // with far points would pay the inner filter's first pass twice).
  // With min_range or a body box the wrapper's own pass always runs (the inner filter knows
  // only the ball).
  const bool exclusions = volume_.hasExclusions();
  const bool asked = ask_inner_ && !exclusions;
  if (asked && inner_->filterInside(cloud, volume_, labels, stats)) {
    if (stats) {
      stats->out_of_range_points = 0;
      stats->near_points = 0;
      stats->total_ms = msSince(t0);
    }
    return;
  }
  // Cheap first pass: most scans have no far point and go to the inner filter without a copy.
  // Far points (outside the ball or the hard limit) and, with min_range or a body box, near ones.
  WorkingVolume volume = volume_;
  std::size_t out_of_range = 0;
  std::size_t near = 0;
  std::size_t finite = 0;
  auto countOutside = [&]() {
    out_of_range = near = finite = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const float x = cloud.x(i), y = cloud.y(i), z = cloud.z(i);
      if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) continue;
      ++finite;
      if (!volume.contains(x, y, z)) {
        ++out_of_range;
      } else if (exclusions && volume.excluded(x, y, z)) {
        ++near;
      }
    }
  };
  countOutside();
  // A cloud with no sensor at its origin (scan_type: airborne, or registered) is not cut by
  // max_range: a survey tile or a map need not lie near the origin. Only the hard limit holds.
  // Most of the cloud beyond the hard box says the same whatever scan_type says (no
  // ground-level scanner has most of its returns 5 km away): a map in projected coordinates
  // with scan_type ground or tls.
  const bool no_sensor =
      out_of_range > 0 && (inner_->noSensorAtOrigin(cloud) ||
                           (out_of_range * 2 > finite && mostBeyondBox(cloud, volume, finite)));
  if (no_sensor && volume.max_range > 0.0) {
    volume.max_range = 0.0;
    countOutside();
  }
  // With exclusions: asked again once they are off.
  ask_inner_ = exclusions || (!asked && out_of_range == 0);
  // A map or survey tile in projected coordinates (UTM, a national grid) lies kilometres from
  // its origin: the hard box moves onto the cloud (recentre()) instead of cutting all of it.
  float shift[3] = {0.f, 0.f, 0.f};
  // recentre() counts the points outside the moved box (which excludes none).
  const bool shifted =
      no_sensor && out_of_range > 0 && recentre(cloud, &out_of_range, &volume, shift);
  if (shifted) near = 0;
  if (out_of_range == 0 && near == 0 && !shifted) {
    inner_->filter(cloud, labels, stats);
    if (stats) {
      stats->out_of_range_points = 0;
      stats->near_points = 0;
      stats->total_ms = msSince(t0);
    }
    return;
  }

  // Pack the finite in-range points in input order: the inner filter sees exactly the cloud it
  // would see without the far, near (and NaN) points, so their neighbours keep their labels.
  xyz_.clear();
  kept_.clear();
  std::size_t invalid = 0;
  for (std::size_t i = 0; i < n; ++i) {
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) {
      ++invalid;
    } else if (volume.contains(x, y, z) && !(exclusions && volume.excluded(x, y, z))) {
      xyz_.push_back(x - shift[0]);
      xyz_.push_back(y - shift[1]);
      xyz_.push_back(z - shift[2]);
      kept_.push_back(i);
    }
  }
  const double pack_ms = msSince(t0);

  FilterStats inner_stats;
  inner_labels_.clear();
  // Also with no point left: the inner filter still reports its scan type (and takes the
  // decision noSensorAtOrigin() kept).
  filterPacked(shifted ? shift : nullptr, &inner_stats);
  if (inner_labels_.size() != kept_.size()) {
    throw std::runtime_error(inner_->name() + " filter returned " +
                             std::to_string(inner_labels_.size()) + " labels for " +
                             std::to_string(kept_.size()) + " points");
  }
  labels->assign(n, kNonGround);
  std::size_t ground = 0;
  for (std::size_t j = 0; j < kept_.size(); ++j) {
    const std::uint8_t l = inner_labels_[j] == kNonGround ? kNonGround : kGround;
    (*labels)[kept_[j]] = l;
    ground += l;
  }
  if (stats) {
    *stats = std::move(inner_stats);
    stats->input_points = n;
    stats->invalid_points = invalid;
    stats->out_of_range_points = out_of_range;
    stats->near_points = near;
    stats->ground_points = ground;
    stats->stage_ms.insert(stats->stage_ms.begin(), {"working volume", pack_ms});
    stats->total_ms = msSince(t0);
  }
}

}  // namespace ground_filter
