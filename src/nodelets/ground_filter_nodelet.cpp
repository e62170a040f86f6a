#include "ground_filter_nodelet.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <geometry_msgs/TransformStamped.h>
#include <std_msgs/Float64.h>
#include <tf2/exceptions.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <chrono>
#include <cstdio>
#include <exception>
#include <utility>

#include "cloud_subscription_helper.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace ground_filter {

namespace {

// Seconds between two log lines of the same kind (rejection reason, stream problem).
constexpr double kLogPeriodS = 5.0;

// Hands the heap's free pages back to the OS. glibc keeps freed memory of its per-thread arenas
// (cloud buffers of changing size, filter rebuilds on reconfigure) mapped: without this the
// manager's RSS crept by ~0.8 MB/min in the 20 Hz soak although nothing leaked (docs/testing.md).
void releaseFreeHeap() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace

GroundFilterNodelet::GroundFilterNodelet() = default;
GroundFilterNodelet::~GroundFilterNodelet() = default;

GroundFilterNodelet::CounterValues GroundFilterNodelet::Counters::values() const {
  CounterValues v;
  v.clouds_in = clouds_in;
  v.clouds_out = clouds_out;
  v.clouds_rejected = clouds_rejected;
  v.clouds_no_transform = clouds_no_transform;
  v.not_cloud = not_cloud;
  v.filter_errors = filter_errors;
  v.invalid_points = invalid_points;
  v.out_of_range_points = out_of_range_points;
  v.config_rejected = config_rejected;
  v.frame_changes = frame_changes;
  v.stamps_backwards = stamps_backwards;
  v.fallbacks = fallbacks;
  return v;
}

void GroundFilterNodelet::onInit() {
  NodeletLazy::onInit();
  pnh_->param("queue_size", queue_size_, 3);
  if (queue_size_ < 1) {
    NODELET_WARN("~queue_size %d < 1, using 1", queue_size_);
    queue_size_ = 1;
  }
  pub_ground_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "ground", 1);
  pub_nonground_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "nonground", 1);
  // Plain advertise: a timing subscriber alone must not start the input subscription.
  pub_time_ = pnh_->advertise<std_msgs::Float64>("processing_time_ms", 10);
  pub_labeled_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "labeled", 1);

  pnh_->param<std::string>("gravity_frame", gravity_frame_, "");
  pnh_->param("tf_timeout", tf_timeout_, 0.1);
  if (!(tf_timeout_ >= 0.0 && tf_timeout_ <= 10.0)) {
    NODELET_WARN("~tf_timeout %g s is outside [0, 10] s, using 0.1 s", tf_timeout_);
    tf_timeout_ = 0.1;
  }
  if (!gravity_frame_.empty()) {
    tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_, *nh_);
    NODELET_INFO(
        "%s: clouds are classified in gravity frame '%s' (tf timeout %.3f s); outputs "
        "keep the input frame",
        methodName().c_str(), gravity_frame_.c_str(), tf_timeout_);
  }

  double period = 1.0;
  pnh_->param("diagnostic_period", period, 1.0);
  if (!(period > 0.0)) period = 1.0;
  updater_ = std::make_unique<diagnostic_updater::Updater>(*nh_, *pnh_, getName());
  updater_->setHardwareID("none");
  updater_->add(methodName() + " ground filter", this, &GroundFilterNodelet::diagnose);
  monitor_.last_diagnose = ros::WallTime::now();
  // Wall time and force_update(): the status keeps coming while a bag's simulated clock is
  // paused or over (Updater::update() would wait for the simulated period).
  diagnostic_timer_ = nh_->createWallTimer(
      ros::WallDuration(period), [this](const ros::WallTimerEvent&) { updater_->force_update(); });
  double trim_period = 1.0;
  pnh_->param("malloc_trim_period", trim_period, 1.0);
  if (!(trim_period >= 0.0 && trim_period <= 3600.0)) {
    NODELET_WARN("~malloc_trim_period %g s is outside [0, 3600] s, using 1 s", trim_period);
    trim_period = 1.0;
  }
  if (trim_period > 0.0) {
    trim_timer_ = nh_->createWallTimer(ros::WallDuration(trim_period),
                                       [](const ros::WallTimerEvent&) { releaseFreeHeap(); });
  }

  onInitFilter();
  // Build the first filter object now, before the input is subscribed: the first cloud of a
  // bag that starts at once is filtered at once (no construction cost, never dropped).
  try {
    updateFilter();
  } catch (const std::exception& e) {
    NODELET_ERROR("%s: building the filter failed (tried again with the first cloud): %s",
                  methodName().c_str(), e.what());
  }
  onInitPostProcess();
}

void GroundFilterNodelet::setFilterFactory(FilterFactory factory, const WorkingVolume& volume,
                                           const std::string& description) {
  auto config = std::make_shared<FilterConfig>();
  config->make = std::move(factory);
  config->volume = volume;
  config->description = description;
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    config_ = std::move(config);
  }
  NODELET_INFO("%s parameters: %s max_range=%g", methodName().c_str(), description.c_str(),
               volume.max_range);
}

void GroundFilterNodelet::reportRejectedConfig(const std::string& what) {
  ++counters_.config_rejected;
  NODELET_ERROR("%s: parameters refused, keeping the previous ones: %s", methodName().c_str(),
                what.c_str());
}

void GroundFilterNodelet::subscribe() {
  ros::SubscribeOptions ops;
  ops.topic = "input";
  ops.queue_size = queue_size_;
  ops.md5sum = ros::message_traits::md5sum<sensor_msgs::PointCloud2>();
  ops.datatype = ros::message_traits::datatype<sensor_msgs::PointCloud2>();
  ops.helper = boost::make_shared<CloudSubscriptionHelper>(
      [this](const sensor_msgs::PointCloud2ConstPtr& msg) { cloudCallback(msg); },
      [this](const std::string& what, const std::string& from) { onNotCloud(what, from); });
  sub_input_ = pnh_->subscribe(ops);
}

void GroundFilterNodelet::unsubscribe() { sub_input_.shutdown(); }

bool GroundFilterNodelet::logNow(int slot, std::uint64_t* suppressed) {
  const ros::WallTime now = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(monitor_mutex_);
  ros::WallTime& last = monitor_.last_log[slot];
  if (!last.isZero() && (now - last).toSec() < kLogPeriodS) {
    ++monitor_.suppressed[slot];
    return false;
  }
  last = now;
  if (suppressed) *suppressed = monitor_.suppressed[slot];
  monitor_.suppressed[slot] = 0;
  return true;
}

void GroundFilterNodelet::logRejected(CloudRejectReason reason, const std::string& message) {
  std::uint64_t suppressed = 0;
  if (!logNow(static_cast<int>(reason), &suppressed)) return;
  std::string more;
  if (suppressed) {
    more = " (" + std::to_string(suppressed) + " more with this reason since the last message)";
  }
  NODELET_ERROR("rejected PointCloud2 on %s (%s): %s; nothing published for it%s",
                sub_input_.getTopic().c_str(), reasonName(reason), message.c_str(), more.c_str());
}

void GroundFilterNodelet::checkStream(const std_msgs::Header& header) {
  std::string old_frame;
  double back_s = 0.0;
  bool frame_changed = false, went_back = false;
  {
    std::lock_guard<std::mutex> lock(monitor_mutex_);
    if (monitor_.have_last) {
      frame_changed = header.frame_id != monitor_.last_frame_id;
      went_back = header.stamp < monitor_.last_stamp;
      if (frame_changed) old_frame = monitor_.last_frame_id;
      if (went_back) back_s = (monitor_.last_stamp - header.stamp).toSec();
    }
    monitor_.last_frame_id = header.frame_id;
    monitor_.last_stamp = header.stamp;
    monitor_.have_last = true;
  }
  if (frame_changed) {
    const auto n = ++counters_.frame_changes;
    if (logNow(kFrameChange)) {
      NODELET_WARN(
          "%s: input frame_id changed from '%s' to '%s' (%llu changes so far); every "
          "cloud is processed and published in its own frame",
          methodName().c_str(), old_frame.c_str(), header.frame_id.c_str(),
          static_cast<unsigned long long>(n));
    }
  }
  if (went_back) {
    const auto n = ++counters_.stamps_backwards;
    if (logNow(kStampBack)) {
      NODELET_WARN(
          "%s: input stamp went back by %.3f s (a bag loop or a restarted driver?) "
          "(%llu times so far); the cloud is processed as usual",
          methodName().c_str(), back_s, static_cast<unsigned long long>(n));
    }
  }
}

bool GroundFilterNodelet::lookupGravityTransform(const std_msgs::Header& header,
                                                 Eigen::Isometry3d* transform, std::string* error) {
  // Polled against wall time: tf2's own timeout runs on ros::Time, which never advances while a
  // bag's simulated clock is paused or over, and the nodelet would hang in this callback.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(tf_timeout_);
  while (true) {
    try {
      const geometry_msgs::TransformStamped t =
          tf_buffer_->lookupTransform(gravity_frame_, header.frame_id, header.stamp);
      const auto& q = t.transform.rotation;
      const auto& v = t.transform.translation;
      transform->linear() = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
      transform->translation() = Eigen::Vector3d(v.x, v.y, v.z);
      transform->makeAffine();
      return true;
    } catch (const tf2::TransformException& e) {
      *error = e.what();
    }
    if (ros::WallTime::now() >= deadline || !ros::ok()) return false;
    ros::WallDuration(0.005).sleep();
  }
}

void GroundFilterNodelet::onNotCloud(const std::string& what, const std::string& publisher) {
  const auto n = ++counters_.not_cloud;
  if (logNow(kNotCloud)) {
    NODELET_WARN("%s: dropped a message on %s from %s: %s (%llu such messages so far)",
                 methodName().c_str(), sub_input_.getTopic().c_str(),
                 publisher.empty() ? "an unknown publisher" : publisher.c_str(), what.c_str(),
                 static_cast<unsigned long long>(n));
  }
}

void GroundFilterNodelet::updateFilter() {
  std::shared_ptr<const FilterConfig> config;
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    config = config_;
  }
  if (!config) {
    NODELET_FATAL("%s: the leaf installed no filter configuration", methodName().c_str());
    return;
  }
  if (config == filter_config_ && filter_) return;
  filter_config_ = config;
  filter_.reset();  // free the old scratch buffers before the new filter allocates its own
  filter_ = std::make_unique<WorkingVolumeFilter>(config->make(), config->volume);
}

void GroundFilterNodelet::cloudCallback(const sensor_msgs::PointCloud2ConstPtr& msg) {
  const auto t0 = std::chrono::steady_clock::now();
  ++counters_.clouds_in;
  checkStream(msg->header);

  CloudLayout layout;
  std::string why;
  const CloudRejectReason reason = checkPointCloud2(*msg, &layout, &why);
  if (reason != CloudRejectReason::kNone) {
    ++counters_.clouds_rejected;
    logRejected(reason, why);
    return;
  }

  // Looked up before the filter lock: it may wait up to tf_timeout_.
  Eigen::Isometry3d to_gravity = Eigen::Isometry3d::Identity();
  const bool transform = !gravity_frame_.empty() && msg->header.frame_id != gravity_frame_;
  if (transform && !lookupGravityTransform(msg->header, &to_gravity, &why)) {
    const auto n = ++counters_.clouds_no_transform;
    if (logNow(kNoTransform)) {
      NODELET_WARN(
          "%s: no transform from '%s' to gravity frame '%s' at t=%.3f within %.3f s: "
          "%s; cloud dropped (%llu so far)",
          methodName().c_str(), msg->header.frame_id.c_str(), gravity_frame_.c_str(),
          msg->header.stamp.toSec(), tf_timeout_, why.c_str(), static_cast<unsigned long long>(n));
    }
    return;
  }

  ProcessedCloud out;
  {
    std::lock_guard<std::mutex> lock(process_mutex_);
    std::string build_error;
    try {
      updateFilter();
      if (filter_) {
        // The working volume is centred on the sensor: its origin in the filter's frame.
        const Eigen::Vector3d o = to_gravity.translation();
        filter_->setOrigin(static_cast<float>(o.x()), static_cast<float>(o.y()),
                           static_cast<float>(o.z()));
      }
    } catch (const std::exception& e) {
      filter_.reset();  // processPointCloud2 publishes the cloud as all non-ground
      build_error = e.what();
    }
    processPointCloud2(*msg, layout, filter_.get(), transform ? &to_gravity : nullptr,
                       pub_labeled_.getNumSubscribers() > 0, &buffers_, &out);
    if (!build_error.empty()) out.filter_error = build_error;
    if (!out.filter_error.empty()) filter_.reset();  // rebuilt from scratch for the next cloud
  }
  publish(out,
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}

void GroundFilterNodelet::publish(const ProcessedCloud& out, double ms) {
  pub_ground_.publish(sensor_msgs::PointCloud2ConstPtr(out.ground));
  pub_nonground_.publish(sensor_msgs::PointCloud2ConstPtr(out.nonground));
  if (out.labeled) pub_labeled_.publish(sensor_msgs::PointCloud2ConstPtr(out.labeled));
  ++counters_.clouds_out;
  counters_.invalid_points += out.counts.invalid;
  counters_.out_of_range_points += out.stats.out_of_range_points;
  const std::size_t points = out.counts.ground + out.counts.nonground;
  if (!out.filter_error.empty()) {
    ++counters_.filter_errors;
    NODELET_ERROR_THROTTLE(kLogPeriodS,
                           "%s filter failed on a %zu-point cloud (published as all "
                           "non-ground): %s",
                           methodName().c_str(), points, out.filter_error.c_str());
  }
  if (!out.labeled_error.empty() && logNow(kLabeled)) {
    NODELET_WARN("%s: ~labeled not published: %s", methodName().c_str(), out.labeled_error.c_str());
  }
  const std::string& note = out.stats.note;
  if (!note.empty()) {
    ++counters_.fallbacks;
    // A new reason (no device, a CUDA error) is logged at once; a repeated one once a minute.
    if (note != logged_note_) {
      NODELET_WARN("%s: %s", methodName().c_str(), note.c_str());
      logged_note_ = note;
    } else {
      NODELET_WARN_THROTTLE(60.0, "%s: %s", methodName().c_str(), note.c_str());
    }
  }
  if (out.stats.out_of_range_points) {
    NODELET_WARN_THROTTLE(kLogPeriodS,
                          "%s: %zu of %zu points outside the working volume (max_range, hard "
                          "limit %.0f m per axis) published as non-ground",
                          methodName().c_str(), out.stats.out_of_range_points, points,
                          kWorkingVolumeHardLimit);
  }
  {
    std::lock_guard<std::mutex> lock(monitor_mutex_);
    monitor_.window_ms_sum += ms;
    monitor_.window_ms_max = std::max(monitor_.window_ms_max, ms);
    ++monitor_.window_clouds;
    monitor_.backend = out.stats.backend;
    if (!note.empty()) monitor_.fallback_note = note;
  }
  NODELET_DEBUG(
      "%s: %zu points in, %zu ground, %zu non-ground (%zu NaN/Inf, %zu out of range), filter "
      "%.2f ms, total %.2f ms",
      methodName().c_str(), points, out.counts.ground, out.counts.nonground, out.counts.invalid,
      out.stats.out_of_range_points, out.stats.total_ms, ms);
  if (pub_time_.getNumSubscribers() > 0) {
    auto t = boost::make_shared<std_msgs::Float64>();
    t->data = ms;
    pub_time_.publish(std_msgs::Float64ConstPtr(t));
  }
}

void GroundFilterNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  using ull = unsigned long long;
  const ros::WallTime now = ros::WallTime::now();
  const CounterValues total = counters_.values();
  CounterValues last;
  double ms_sum, ms_max, dt;
  std::uint64_t clouds;
  std::string backend, note;
  {
    std::lock_guard<std::mutex> lock(monitor_mutex_);
    ms_sum = monitor_.window_ms_sum;
    ms_max = monitor_.window_ms_max;
    clouds = monitor_.window_clouds;
    monitor_.window_ms_sum = monitor_.window_ms_max = 0.0;
    monitor_.window_clouds = 0;
    backend = monitor_.backend;
    note = monitor_.fallback_note;
    dt = std::max(1e-6, (now - monitor_.last_diagnose).toSec());
    monitor_.last_diagnose = now;
    last = monitor_.last_counts;
    monitor_.last_counts = total;
  }
  bool have_config;
  {
    std::lock_guard<std::mutex> lock(config_mutex_);
    have_config = static_cast<bool>(config_);
  }
  // Drop reasons and stream irregularities: name, count since start, count since last update.
  struct Item {
    const char* name;
    std::uint64_t total;
    std::uint64_t delta;
  };
  auto item = [](const char* name, std::uint64_t CounterValues::*field, const CounterValues& t,
                 const CounterValues& l) {
    return Item{name, t.*field, t.*field - l.*field};
  };
  const Item drops[] = {
      item("malformed", &CounterValues::clouds_rejected, total, last),
      item("no transform", &CounterValues::clouds_no_transform, total, last),
      item("not PointCloud2", &CounterValues::not_cloud, total, last),
  };
  const Item stream[] = {
      item("frame_id changes", &CounterValues::frame_changes, total, last),
      item("stamps going back", &CounterValues::stamps_backwards, total, last),
  };
  const double in_hz = (total.clouds_in - last.clouds_in) / dt;
  const double out_hz = (total.clouds_out - last.clouds_out) / dt;

  char head[128];
  std::snprintf(head, sizeof(head), "%.1f Hz in, %.1f Hz out", in_hz, out_hz);
  std::string problems;
  for (const Item& d : drops) {
    if (d.delta) {
      problems +=
          (problems.empty() ? "" : ", ") + std::to_string(d.delta) + " dropped (" + d.name + ")";
    }
  }
  for (const Item& s : stream) {
    if (s.delta)
      problems += (problems.empty() ? "" : ", ") + std::to_string(s.delta) + " " + s.name;
  }
  if (!have_config) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "no filter configuration");
  } else if (!problems.empty()) {
    char since[48];
    std::snprintf(since, sizeof(since), " in the last %.1f s", dt);
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   std::string(head) + "; " + problems + since);
  } else {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, head);
  }

  status.add("method", methodName());
  status.add("backend", backend.empty() ? std::string("n/a (no neighbour search)") : backend);
  status.add("gravity frame",
             gravity_frame_.empty() ? std::string("(input frame)") : gravity_frame_);
  status.addf("input rate [Hz]", "%.2f", in_hz);
  status.addf("output rate [Hz]", "%.2f", out_hz);
  if (clouds) {
    status.addf("processing time mean [ms]", "%.2f", ms_sum / clouds);
    status.addf("processing time max [ms]", "%.2f", ms_max);
  } else {
    status.add("processing time mean [ms]", "n/a (no cloud)");
    status.add("processing time max [ms]", "n/a (no cloud)");
  }
  status.add("clouds in", static_cast<ull>(total.clouds_in));
  status.add("clouds out", static_cast<ull>(total.clouds_out));
  status.add("dropped", static_cast<ull>(total.dropped()));
  for (const Item& d : drops)
    status.add(std::string("dropped: ") + d.name, static_cast<ull>(d.total));
  status.add("invalid points (NaN/Inf)", static_cast<ull>(total.invalid_points));
  status.add("out of range points", static_cast<ull>(total.out_of_range_points));
  status.add("filter errors (published as non-ground)", static_cast<ull>(total.filter_errors));
  status.add("fallbacks", static_cast<ull>(total.fallbacks));
  status.add("last fallback", note.empty() ? std::string("none") : note);
  for (const Item& s : stream) status.add(s.name, static_cast<ull>(s.total));
  status.add("refused parameter sets", static_cast<ull>(total.config_rejected));
}

}  // namespace ground_filter
