#include "ground_filter_nodelet.h"

#include <boost/make_shared.hpp>
#include <chrono>
#include <exception>
#include <map>
#include <utility>

#include "cloud_subscription_helper.h"
#include "ground_filter/build_info.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace ground_filter {

namespace {

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
  NODELET_INFO("%s: %s", methodName().c_str(), buildInfo().summary.c_str());
  checkParams();
  // Ranges checked by checkParams(): a value outside was refused, the default applies.
  pnh_->param("queue_size", queue_size_, 3);
  input_ = std::make_unique<InputReporter>(getName(), methodName(), pnh_->resolveName("input"),
                                           queue_size_, &monitor_);
  outputs_ = std::make_unique<OutputPublisher>(getName(), methodName(), &monitor_);
  outputs_->advertise(*pnh_, [this](const std::string& topic) {
    return advertise<sensor_msgs::PointCloud2>(*pnh_, topic, 1);
  });

  std::string gravity_frame;
  double tf_timeout = 0.1;
  pnh_->param<std::string>("gravity_frame", gravity_frame, "");
  pnh_->param("tf_timeout", tf_timeout, 0.1);
  if (!gravity_frame.empty()) {
    // The single-threaded queue (nh_ is NodeletLazy's multi-threaded one): clouds come out one
    // at a time, in the order their transforms arrive.
    tf_wait_ = std::make_unique<TfWaitQueue>(
        getNodeHandle(), gravity_frame, tf_timeout, queue_size_,
        [this](const sensor_msgs::PointCloud2ConstPtr& msg, const CloudLayout& layout,
               const Eigen::Isometry3d& to_gravity,
               TfWaitQueue::Clock::time_point t0) { processCloud(msg, layout, &to_gravity, t0); },
        [this](const sensor_msgs::PointCloud2ConstPtr& msg, const std::string& why) {
          input_->noTransform(*msg, tf_wait_->frame(), why);
        });
    NODELET_INFO(
        "%s: clouds are classified in gravity frame '%s' (tf timeout %.3f s); outputs "
        "keep the input frame",
        methodName().c_str(), gravity_frame.c_str(), tf_timeout);
  }
  setUpDiagnostics();

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

void GroundFilterNodelet::setUpDiagnostics() {
  double period = 1.0;
  pnh_->param("diagnostic_period", period, 1.0);
  updater_ = std::make_unique<diagnostic_updater::Updater>(*nh_, *pnh_, getName());
  updater_->setHardwareID("none");
  updater_->add(
      methodName() + " ground filter", [this](diagnostic_updater::DiagnosticStatusWrapper& status) {
        monitor_.diagnose(status, methodName(), tf_wait_ ? tf_wait_->frame() : "", haveConfig());
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
        ros::WallDuration(trim_period),
        [this](const ros::WallTimerEvent&) {
          // Idle for a whole period: the pooled messages go back too.
          if (!active_.exchange(false)) clearPools();
          releaseFreeHeap();
        },
        false, false);
  }
}

void GroundFilterNodelet::clearPools() {
  input_pool_.clear();
  output_pools_.ground.clear();
  output_pools_.nonground.clear();
  output_pools_.labeled.clear();
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
      [this](const std::string& what, const std::string& from) { input_->notCloud(what, from); },
      &input_pool_);
  // The single-threaded queue, not NodeletLazy's multi-threaded one: there a cloud arriving
  // while the previous one is filtered makes roscpp answer TryAgain, and the manager's threads
  // re-queue it in a busy loop for the whole filter run (perf: a quarter of the manager's CPU,
  // taken from the filter's own threads; docs/ros_integration.md, "A robot's load").
  ops.callback_queue = getNodeHandle().getCallbackQueue();
  sub_input_ = pnh_->subscribe(ops);
}

void GroundFilterNodelet::unsubscribe() { sub_input_.shutdown(); }

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
  active_ = true;
  ++monitor_.counters().clouds_in;
  input_->checkStream(msg->header);

  CloudLayout layout;
  std::string why;
  const CloudRejectReason reason = checkPointCloud2(*msg, &layout, &why);
  if (reason != CloudRejectReason::kNone) {
    input_->rejected(reason, why);
    return;
  }
  if (!tf_wait_ || msg->header.frame_id == tf_wait_->frame()) {
    processCloud(msg, layout, nullptr, t0);
  } else {
    tf_wait_->add(msg, layout, t0);  // processCloud() once its transform is there
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
      if (filter_) setSensorPose(filter_.get(), pose);
    } catch (const std::exception& e) {
      filter_.reset();  // filterPointCloud2 labels the cloud all non-ground
      build_error = e.what();
    }
    filterPointCloud2(*msg, layout, filter_.get(), to_gravity, &buffers_, &out);
    if (!build_error.empty()) out.filter_error = build_error;
    // The heights come from the labels and go into the outputs as their records are copied.
    const bool want_labeled = outputs_->wantLabeled();
    HagOutputs& hag_outputs = outputs_->hag();
    const std::vector<float>* heights = hag_outputs.process(
        *msg, layout, to_gravity, buffers_, to_gravity ? tf_wait_->frame() : msg->header.frame_id,
        out, want_labeled, &hag);
    RecordFloatField height_field;
    height_field.name = kHeightFieldName;
    height_field.values = heights;
    writeOutputs(*msg, layout, want_labeled, &buffers_, &out, &output_pools_,
                 heights ? &height_field : nullptr, hag_outputs.fieldInSplit());
    if (!out.filter_error.empty()) {
      filter_.reset();  // rebuilt from scratch for the next cloud
    } else if (release_.afterCloud(static_cast<std::size_t>(msg->width) * msg->height)) {
      filter_.reset();  // a rare large cloud's buffers go; the next clouds size new ones
      buffers_ = CloudProcessingBuffers();
      clearPools();
      ++monitor_.counters().buffer_releases;
    }
  }
  outputs_->publish(
      out, hag,
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}

}  // namespace ground_filter
