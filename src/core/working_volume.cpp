#include "ground_filter/working_volume.h"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace ground_filter {

void WorkingVolume::validate() const {
  if (!(max_range == 0.0 || (max_range > 0.0 && max_range <= kWorkingVolumeHardLimit))) {
    throw std::invalid_argument("max_range = " + std::to_string(max_range) +
                                " m is outside 0 (off) or (0, " +
                                std::to_string(kWorkingVolumeHardLimit) + "] m");
  }
  for (float o : origin) {
    if (!std::isfinite(o)) throw std::invalid_argument("working volume origin is not finite");
  }
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

void WorkingVolumeFilter::filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                                 FilterStats* stats) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const std::size_t n = cloud.size();
  // The usual case: the inner filter tests the volume on its way, no pass here. Not asked again
  // after it declined until the wrapper's own pass finds every point inside (a stream of scans
  // with far points would pay the inner filter's first pass twice).
  const bool asked = ask_inner_;
  if (asked && inner_->filterInside(cloud, volume_, labels, stats)) {
    if (stats) {
      stats->out_of_range_points = 0;
      stats->total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    }
    return;
  }
  // Cheap first pass: most scans have no far point and go to the inner filter without a copy.
  auto countOutside = [&](const WorkingVolume& v) {
    std::size_t count = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const float x = cloud.x(i), y = cloud.y(i), z = cloud.z(i);
      // contains() is false for NaN/Inf too: only then tell the two apart.
      if (!v.contains(x, y, z) && std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) {
        ++count;
      }
    }
    return count;
  };
  WorkingVolume volume = volume_;
  std::size_t out_of_range = countOutside(volume);
  // An airborne scan (scan_type) is not cut by max_range: a survey tile need not lie near the
  // origin. Only the hard limit holds.
  if (out_of_range > 0 && volume.max_range > 0.0 && inner_->airborneScan(cloud)) {
    volume.max_range = 0.0;
    out_of_range = countOutside(volume);
  }
  ask_inner_ = !asked && out_of_range == 0;
  if (out_of_range == 0) {
    inner_->filter(cloud, labels, stats);
    if (stats) {
      stats->out_of_range_points = 0;
      stats->total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    }
    return;
  }

  // Pack the finite in-range points in input order: the inner filter sees exactly the cloud it
  // would see without the far (and NaN) points, so their neighbours keep their labels.
  xyz_.clear();
  kept_.clear();
  std::size_t invalid = 0;
  for (std::size_t i = 0; i < n; ++i) {
    float x, y, z;
    if (!cloud.get(i, &x, &y, &z)) {
      ++invalid;
    } else if (volume.contains(x, y, z)) {
      xyz_.push_back(x);
      xyz_.push_back(y);
      xyz_.push_back(z);
      kept_.push_back(i);
    }
  }
  const double pack_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();

  FilterStats inner_stats;
  inner_labels_.clear();
  // Also with no point left: the inner filter still reports its scan type (and takes the
  // decision airborneScan() kept).
  inner_->filter(CloudView::packedXyz(xyz_.data(), kept_.size()), &inner_labels_, &inner_stats);
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
    stats->ground_points = ground;
    stats->stage_ms.insert(stats->stage_ms.begin(), {"working volume", pack_ms});
    stats->total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  }
}

}  // namespace ground_filter
