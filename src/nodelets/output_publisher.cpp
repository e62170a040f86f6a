#include "output_publisher.h"

#include <nodelet/nodelet.h>
#include <std_msgs/Float64.h>

#include <boost/make_shared.hpp>

#include "ground_filter/working_volume.h"

namespace ground_filter {

OutputPublisher::OutputPublisher(const std::string& name, const std::string& method,
                                 NodeletMonitor* monitor)
    : name_(name), method_(method), monitor_(monitor) {}

void OutputPublisher::advertise(ros::NodeHandle& pnh, const AdvertiseLazy& lazy) {
  pub_ground_ = lazy("ground");
  pub_nonground_ = lazy("nonground");
  // Plain advertise: a timing subscriber alone must not start the input subscription.
  pub_time_ = pnh.advertise<std_msgs::Float64>("processing_time_ms", 10);
  pub_labeled_ = lazy("labeled");
  hag_.init(pnh, lazy("ground_surface"), lazy("obstacles"));
}

void OutputPublisher::publish(const ProcessedCloud& out, const HagClouds& hag, double ms) {
  pub_ground_.publish(sensor_msgs::PointCloud2ConstPtr(out.ground));
  pub_nonground_.publish(sensor_msgs::PointCloud2ConstPtr(out.nonground));
  if (out.labeled) pub_labeled_.publish(sensor_msgs::PointCloud2ConstPtr(out.labeled));
  hag_.publish(hag);
  NodeletMonitor::Counters& counters = monitor_->counters();
  ++counters.clouds_out;
  counters.invalid_points += out.counts.invalid;
  counters.out_of_range_points += out.stats.out_of_range_points;
  counters.near_points += out.stats.near_points;
  const std::size_t points = out.counts.ground + out.counts.nonground;
  const char* method = method_.c_str();
  if (!out.filter_error.empty()) {
    ++counters.filter_errors;
    NODELET_ERROR_THROTTLE(NodeletMonitor::kLogPeriodS,
                           "%s filter failed on a %zu-point cloud (published as all "
                           "non-ground): %s",
                           method, points, out.filter_error.c_str());
  }
  if (!out.labeled_error.empty() && monitor_->logNow(NodeletMonitor::kLabeled)) {
    NODELET_WARN("%s: ~labeled not published: %s", method, out.labeled_error.c_str());
  }
  const std::string& field_error = out.field_error.empty() ? hag.error : out.field_error;
  if (!field_error.empty() && monitor_->logNow(NodeletMonitor::kLabeled)) {
    NODELET_WARN("%s: no height_above_ground field: %s", method, field_error.c_str());
  }
  const std::string& note = out.stats.note;
  if (!note.empty()) {
    ++counters.fallbacks;
    // A new reason (no device, a CUDA error, a tilted scan) is logged at once; a repeated one,
    // its numbers aside (a ramp's lean changes from scan to scan), once a minute.
    NodeletMonitor::noteKind(note, &note_kind_);
    const ros::WallTime now = ros::WallTime::now();
    if (note_kind_ != logged_note_ || (now - note_logged_at_).toSec() >= 60.0) {
      NODELET_WARN("%s: %s", method, note.c_str());
      logged_note_ = note_kind_;
      note_logged_at_ = now;
    }
  }
  if (out.stats.out_of_range_points) {
    NODELET_WARN_THROTTLE(NodeletMonitor::kLogPeriodS,
                          "%s: %zu of %zu points outside the working volume (max_range, hard "
                          "limit %.0f m per axis) published as non-ground",
                          method, out.stats.out_of_range_points, points, kWorkingVolumeHardLimit);
  }
  const std::string& reason = out.stats.scan_reason;
  monitor_->recordCloud(ms, out.stats.backend, note,
                        out.stats.scan_type + (reason.empty() ? "" : " (" + reason + ")"));
  NODELET_DEBUG(
      "%s: %zu points in, %zu ground, %zu non-ground (%zu NaN/Inf, %zu out of range), filter "
      "%.2f ms, total %.2f ms",
      method, points, out.counts.ground, out.counts.nonground, out.counts.invalid,
      out.stats.out_of_range_points, out.stats.total_ms, ms);
  if (pub_time_.getNumSubscribers() > 0) {
    auto t = boost::make_shared<std_msgs::Float64>();
    t->data = ms;
    pub_time_.publish(std_msgs::Float64ConstPtr(t));
  }
}

}  // namespace ground_filter
