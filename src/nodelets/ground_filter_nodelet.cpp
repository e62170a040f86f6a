#include "ground_filter_nodelet.h"

#include <std_msgs/Float64.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <chrono>
#include <cstdio>
#include <exception>
#include <map>
#include <utility>

#include "cloud_subscription_helper.h"
#include "simd/simd.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace ground_filter {

namespace {

constexpr double kLogPeriodS = NodeletMonitor::kLogPeriodS;

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

void GroundFilterNodelet::checkParams() {
  std::vector<std::string> names;
  pnh_->getParamNames(names);
  const std::string prefix = pnh_->getNamespace() + "/";
  std::map<std::string, XmlRpc::XmlRpcValue> set;
  for (const std::string& n : names) {
    if (n.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string key = n.substr(prefix.size(), n.find('/', prefix.size()) - prefix.size());
    if (set.count(key)) continue;
    XmlRpc::XmlRpcValue v;
    if (pnh_->getParam(key, v)) set[key] = v;
  }
  std::vector<ParamCheck> known = baseParamChecks();
  for (const ParamCheck& c : hagParamChecks()) known.push_back(c);
  for (const ParamCheck& c : leafParams()) known.push_back(c);
  std::vector<std::string> refused;
  for (const std::string& e : checkPrivateParams(set, known, &refused)) {
    ++monitor_.counters().config_rejected;
    monitor_.recordRefused("~" + e);
    NODELET_ERROR("%s: parameter ~%s; refused, the default stays", methodName().c_str(), e.c_str());
  }
  for (const std::string& key : refused) pnh_->deleteParam(key);

  XmlRpc::XmlRpcValue box;
  if (pnh_->getParam("body_box", box)) {  // type checked above: a list of numbers
    std::vector<double> values;
    for (int i = 0; i < box.size(); ++i) {
      values.push_back(box[i].getType() == XmlRpc::XmlRpcValue::TypeInt
                           ? static_cast<double>(static_cast<int>(box[i]))
                           : static_cast<double>(box[i]));
    }
    WorkingVolume v;
    v.body_box = values;
    try {
      v.validate();
      body_box_ = values;
    } catch (const std::invalid_argument& e) {
      ++monitor_.counters().config_rejected;
      monitor_.recordRefused(std::string("~body_box: ") + e.what());
      NODELET_ERROR("%s: parameter ~body_box: %s; refused, no body box", methodName().c_str(),
                    e.what());
      pnh_->deleteParam("body_box");
    }
  }
  if (!body_box_.empty()) {
    NODELET_INFO(
        "%s: body box [%g, %g] x [%g, %g] x [%g, %g] m (input frame): its points are "
        "non-ground",
        methodName().c_str(), body_box_[0], body_box_[1], body_box_[2], body_box_[3], body_box_[4],
        body_box_[5]);
  }
}

void GroundFilterNodelet::onInit() {
  NodeletLazy::onInit();
  NODELET_INFO("%s: %s", methodName().c_str(), simd::describe().c_str());
  checkParams();
  // Ranges checked by checkParams(): a value outside was refused, the default applies.
  pnh_->param("queue_size", queue_size_, 3);
  pub_ground_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "ground", 1);
  pub_nonground_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "nonground", 1);
  // Plain advertise: a timing subscriber alone must not start the input subscription.
  pub_time_ = pnh_->advertise<std_msgs::Float64>("processing_time_ms", 10);
  pub_labeled_ = advertise<sensor_msgs::PointCloud2>(*pnh_, "labeled", 1);
  hag_.init(*pnh_, advertise<sensor_msgs::PointCloud2>(*pnh_, "ground_surface", 1),
            advertise<sensor_msgs::PointCloud2>(*pnh_, "obstacles", 1));

  std::string gravity_frame;
  double tf_timeout = 0.1;
  pnh_->param<std::string>("gravity_frame", gravity_frame, "");
  pnh_->param("tf_timeout", tf_timeout, 0.1);
  if (!gravity_frame.empty()) {
    gravity_ = std::make_unique<GravityTransform>(*nh_, gravity_frame, tf_timeout);
    // Started while clouds wait for their transform (drainPending()), stopped when none does.
    tf_retry_timer_ = nh_->createWallTimer(
        ros::WallDuration(0.005), [this](const ros::WallTimerEvent&) { drainPending(); }, false,
        false);
    NODELET_INFO(
        "%s: clouds are classified in gravity frame '%s' (tf timeout %.3f s); outputs "
        "keep the input frame",
        methodName().c_str(), gravity_frame.c_str(), tf_timeout);
  }

  double period = 1.0;
  pnh_->param("diagnostic_period", period, 1.0);
  updater_ = std::make_unique<diagnostic_updater::Updater>(*nh_, *pnh_, getName());
  updater_->setHardwareID("none");
  updater_->add(
      methodName() + " ground filter", [this](diagnostic_updater::DiagnosticStatusWrapper& status) {
        monitor_.diagnose(status, methodName(), gravity_ ? gravity_->frame() : "", haveConfig());
      });
  // Wall time and force_update(): the status keeps coming while a bag's simulated clock is
  // paused or over (Updater::update() would wait for the simulated period).
  // Started by afterInit() (nodelet 1.10.0 loses a timer that fires while onInit() runs).
  diagnostic_timer_ = nh_->createWallTimer(
      ros::WallDuration(period), [this](const ros::WallTimerEvent&) { updater_->force_update(); },
      false, false);
  double trim_period = 1.0;
  pnh_->param("malloc_trim_period", trim_period, 1.0);
  if (trim_period > 0.0) {
    trim_timer_ = nh_->createWallTimer(
        ros::WallDuration(trim_period), [](const ros::WallTimerEvent&) { releaseFreeHeap(); },
        false, false);
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
  // nodelet 1.10.0 (Debian 11; fixed in 1.10.1, nodelet_core #106) drops every callback queued
  // while onInit() runs: a subscriber that connected meanwhile never started the lazy input, and
  // a timer that fired then never fired again. Once the queue runs: look again, start the timers.
  after_init_timer_ = nh_->createWallTimer(
      ros::WallDuration(0.05), [this](const ros::WallTimerEvent&) { afterInit(); }, true);
}

void GroundFilterNodelet::afterInit() {
  diagnostic_timer_.start();
  if (trim_timer_.isValid()) trim_timer_.start();
  if (!lazy_) return;
  boost::mutex::scoped_lock lock(connection_mutex_);
  if (connection_status_ == nodelet_topic_tools::SUBSCRIBED) return;
  for (const ros::Publisher& pub : publishers_) {
    if (pub.getNumSubscribers() > 0) {
      subscribe();
      connection_status_ = nodelet_topic_tools::SUBSCRIBED;
      ever_subscribed_ = true;
      return;
    }
  }
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
  NODELET_INFO("%s parameters: %s max_range=%g min_range=%g", methodName().c_str(),
               description.c_str(), volume.max_range, volume.min_range);
}

void GroundFilterNodelet::reportRejectedConfig(const std::string& what) {
  ++monitor_.counters().config_rejected;
  monitor_.recordRefused(what);
  NODELET_ERROR("%s: parameters refused, keeping the previous ones: %s", methodName().c_str(),
                what.c_str());
}

void GroundFilterNodelet::subscribe() {
  monitor_.restartStream();  // clouds sent while unsubscribed are not lost ones
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

void GroundFilterNodelet::logRejected(CloudRejectReason reason, const std::string& message) {
  std::uint64_t suppressed = 0;
  if (!monitor_.logNow(static_cast<int>(reason), &suppressed)) return;
  std::string more;
  if (suppressed) {
    more = " (" + std::to_string(suppressed) + " more with this reason since the last message)";
  }
  NODELET_ERROR("rejected PointCloud2 on %s (%s): %s; nothing published for it%s",
                sub_input_.getTopic().c_str(), reasonName(reason), message.c_str(), more.c_str());
}

void GroundFilterNodelet::countAndWarn(std::atomic<std::uint64_t>* counter, int slot,
                                       const std::string& what, const char* then) {
  const auto n = ++*counter;
  if (monitor_.logNow(slot)) {
    NODELET_WARN("%s: %s (%llu so far)%s", methodName().c_str(), what.c_str(),
                 static_cast<unsigned long long>(n), then);
  }
}

void GroundFilterNodelet::checkStream(const std_msgs::Header& header) {
  const NodeletMonitor::StreamChange change = monitor_.checkStream(header);
  if (change.frame_changed) {
    countAndWarn(
        &monitor_.counters().frame_changes, NodeletMonitor::kFrameChange,
        "input frame_id changed from '" + change.old_frame + "' to '" + header.frame_id + "'",
        "; every cloud is processed and published in its own frame");
  }
  if (change.gap.lost) {
    const NodeletMonitor::StreamChange::Gap& gap = change.gap;
    const auto n = (monitor_.counters().clouds_lost += gap.lost);
    if (monitor_.logNow(NodeletMonitor::kLost)) {
      char how[96];
      if (gap.by_seq) {
        std::snprintf(how, sizeof(how), "seq %u -> %u", gap.seq_from, gap.seq_to);
      } else {
        std::snprintf(how, sizeof(how), "stamp step %.3f s, input period %.3f s", gap.step_s,
                      gap.period_s);
      }
      NODELET_WARN(
          "%s: %llu input cloud%s lost before the filter (%s; %llu so far): the input queue "
          "(~queue_size %d) was full while the filter was busy, or the sender skipped them",
          methodName().c_str(), static_cast<unsigned long long>(gap.lost), gap.lost == 1 ? "" : "s",
          how, static_cast<unsigned long long>(n), queue_size_);
    }
  }
  if (change.went_back) {
    char by[64];
    std::snprintf(by, sizeof(by), "%.3f s", change.back_s);
    countAndWarn(
        &monitor_.counters().stamps_backwards, NodeletMonitor::kStampBack,
        std::string("input stamp went back by ") + by + " (a bag loop or a restarted driver?)",
        "; the cloud is processed as usual");
  }
}

void GroundFilterNodelet::onNotCloud(const std::string& what, const std::string& publisher) {
  countAndWarn(&monitor_.counters().not_cloud, NodeletMonitor::kNotCloud,
               "dropped a message on " + sub_input_.getTopic() + " from " +
                   (publisher.empty() ? std::string("an unknown publisher") : publisher) + ": " +
                   what,
               "");
}

bool GroundFilterNodelet::haveConfig() {
  std::lock_guard<std::mutex> lock(config_mutex_);
  return static_cast<bool>(config_);
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
  NodeletMonitor::Counters& counters = monitor_.counters();
  ++counters.clouds_in;
  checkStream(msg->header);

  CloudLayout layout;
  std::string why;
  const CloudRejectReason reason = checkPointCloud2(*msg, &layout, &why);
  if (reason != CloudRejectReason::kNone) {
    ++counters.clouds_rejected;
    logRejected(reason, why);
    return;
  }

  if (!gravity_ || msg->header.frame_id == gravity_->frame()) {
    processCloud(msg, layout, nullptr, t0);
    return;
  }
  // Queued, then taken at once when the transform is there: a cloud whose transform is late
  // waits in the queue, not in this thread.
  {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    pending_.push_back(PendingCloud{
        msg, layout, ros::WallTime::now() + ros::WallDuration(gravity_->timeout()), t0});
    if (pending_.size() > static_cast<std::size_t>(queue_size_)) {
      const sensor_msgs::PointCloud2ConstPtr old = pending_.front().msg;
      pending_.pop_front();
      char when[64];
      std::snprintf(when, sizeof(when), "' at t=%.3f: ", old->header.stamp.toSec());
      countAndWarn(&counters.clouds_no_transform, NodeletMonitor::kNoTransform,
                   "no transform from '" + old->header.frame_id + "' to gravity frame '" +
                       gravity_->frame() + when + std::to_string(queue_size_) +
                       " newer clouds wait for theirs (~queue_size); cloud dropped",
                   "");
    }
  }
  drainPending();
}

void GroundFilterNodelet::drainPending() {
  std::lock_guard<std::mutex> drain(drain_mutex_);
  while (true) {
    PendingCloud cloud;
    {
      std::lock_guard<std::mutex> lock(pending_mutex_);
      if (pending_.empty()) {
        tf_retry_timer_.stop();
        return;
      }
      cloud = pending_.front();
    }
    Eigen::Isometry3d to_gravity = Eigen::Isometry3d::Identity();
    std::string why;
    const bool found = gravity_->lookup(cloud.msg->header, &to_gravity, &why);
    if (!found && ros::WallTime::now() < cloud.deadline && ros::ok()) {
      tf_retry_timer_.start();  // no-op when running
      return;
    }
    {
      std::lock_guard<std::mutex> lock(pending_mutex_);
      // Only this function pops the front, besides an overflow that dropped it meanwhile.
      if (pending_.empty() || pending_.front().msg != cloud.msg) continue;
      pending_.pop_front();
    }
    if (found) {
      processCloud(cloud.msg, cloud.layout, &to_gravity, cloud.t0);
      continue;
    }
    char when[96];
    std::snprintf(when, sizeof(when),
                  "' at t=%.3f within %.3f s: ", cloud.msg->header.stamp.toSec(),
                  gravity_->timeout());
    countAndWarn(&monitor_.counters().clouds_no_transform, NodeletMonitor::kNoTransform,
                 "no transform from '" + cloud.msg->header.frame_id + "' to gravity frame '" +
                     gravity_->frame() + when + why + "; cloud dropped",
                 "");
  }
}

void GroundFilterNodelet::processCloud(const sensor_msgs::PointCloud2ConstPtr& msg,
                                       const CloudLayout& layout,
                                       const Eigen::Isometry3d* to_gravity,
                                       std::chrono::steady_clock::time_point t0) {
  const Eigen::Isometry3d identity = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d& pose = to_gravity ? *to_gravity : identity;
  // Where the cloud lies, for the diagnostics: a survey tile in map coordinates can lie
  // kilometres from rviz's default view. 4096 records read at most.
  double centre[3];
  const bool finite = sampledCentre(*msg, layout, 4096, centre);
  monitor_.recordCentre(finite ? centre : nullptr, msg->header.frame_id);
  ProcessedCloud out;
  HagClouds hag;
  {
    std::lock_guard<std::mutex> lock(process_mutex_);
    std::string build_error;
    try {
      updateFilter();
      if (filter_) {
        // The working volume is centred on the sensor: its pose in the filter's frame (the
        // body box is given in the input frame).
        const Eigen::Vector3d o = pose.translation();
        const Eigen::Matrix3d r = pose.linear();
        const float origin[3] = {static_cast<float>(o.x()), static_cast<float>(o.y()),
                                 static_cast<float>(o.z())};
        float rotation[9];
        for (int i = 0; i < 9; ++i) rotation[i] = static_cast<float>(r(i / 3, i % 3));
        filter_->setPose(origin, rotation);
      }
    } catch (const std::exception& e) {
      filter_.reset();  // processPointCloud2 publishes the cloud as all non-ground
      build_error = e.what();
    }
    processPointCloud2(*msg, layout, filter_.get(), to_gravity,
                       pub_labeled_.getNumSubscribers() > 0, &buffers_, &out);
    if (!build_error.empty()) out.filter_error = build_error;
    hag_.process(*msg, layout, to_gravity, buffers_,
                 to_gravity ? gravity_->frame() : msg->header.frame_id, &out, &hag);
    if (!out.filter_error.empty()) filter_.reset();  // rebuilt from scratch for the next cloud
  }
  publish(out,
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  hag_.publish(hag);
  if (!hag.error.empty() && monitor_.logNow(NodeletMonitor::kLabeled)) {
    NODELET_WARN("%s: no height_above_ground field: %s", methodName().c_str(), hag.error.c_str());
  }
}

void GroundFilterNodelet::publish(const ProcessedCloud& out, double ms) {
  pub_ground_.publish(sensor_msgs::PointCloud2ConstPtr(out.ground));
  pub_nonground_.publish(sensor_msgs::PointCloud2ConstPtr(out.nonground));
  if (out.labeled) pub_labeled_.publish(sensor_msgs::PointCloud2ConstPtr(out.labeled));
  NodeletMonitor::Counters& counters = monitor_.counters();
  ++counters.clouds_out;
  counters.invalid_points += out.counts.invalid;
  counters.out_of_range_points += out.stats.out_of_range_points;
  counters.near_points += out.stats.near_points;
  const std::size_t points = out.counts.ground + out.counts.nonground;
  if (!out.filter_error.empty()) {
    ++counters.filter_errors;
    NODELET_ERROR_THROTTLE(kLogPeriodS,
                           "%s filter failed on a %zu-point cloud (published as all "
                           "non-ground): %s",
                           methodName().c_str(), points, out.filter_error.c_str());
  }
  if (!out.labeled_error.empty() && monitor_.logNow(NodeletMonitor::kLabeled)) {
    NODELET_WARN("%s: ~labeled not published: %s", methodName().c_str(), out.labeled_error.c_str());
  }
  const std::string& note = out.stats.note;
  if (!note.empty()) {
    ++counters.fallbacks;
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
  monitor_.recordCloud(ms, out.stats.backend, note,
                       out.stats.scan_type + (out.stats.scan_reason.empty() ? "" : " (") +
                           out.stats.scan_reason + (out.stats.scan_reason.empty() ? "" : ")"));
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

}  // namespace ground_filter
