#ifndef GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <nodelet_topic_tools/nodelet_lazy.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <chrono>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "gravity_transform.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/working_volume.h"
#include "hag_outputs.h"
#include "nodelet_monitor.h"
#include "param_check.h"
#include "params_from_config.h"
#include "point_cloud2.h"

namespace ground_filter {

/// \brief Base of the ground filter nodelets: `~input` (sensor_msgs/PointCloud2) is split into
///        `~ground` and `~nonground`, subscribed lazily (only while an output has subscribers, or
///        always with `~lazy: false`).
///
/// Owns validation, the zero-copy view, the zero-loss split, timing and the swap of filter
/// configurations. A leaf only builds its filter: in onInitFilter() it starts its
/// dynamic_reconfigure server, whose callback validates the new parameters and calls
/// setFilterFactory(). Clouds are processed with a private filter object (scratch buffers are
/// kept between clouds), rebuilt when the factory changed.
///
/// Leaves may advertise more lazy outputs with advertise<>() in onInitFilter().
///
/// Private parameters (read once at start): `~queue_size` (int, default 3) of the input
/// subscription; `~lazy` (bool, default true) from NodeletLazy; `~gravity_frame` (string,
/// default "": off) frame whose z axis points up: each cloud is classified after a tf2 transform
/// into it (outputs keep the input frame, header and records); `~tf_timeout` (double, default
/// 0.1 s, wall time) wait for that transform before the cloud is dropped and counted: a cloud
/// whose transform is not there yet waits in a queue (at most `~queue_size` clouds, the oldest
/// dropped and counted beyond) that a wall timer retries every 5 ms, so no manager thread is
/// held while it waits; clouds leave the queue in arrival order;
/// `~diagnostic_period` (double, default 1 s) of the /diagnostics status;
/// `~malloc_trim_period` (double, default 1 s, 0 = off; glibc only) period at which the heap's
/// free pages are handed back to the OS (malloc_trim), so the manager's RSS stays flat.
/// Extra outputs: `~labeled` (lazy; the input cloud plus a uint8 `ground` field, see
/// makeLabeledCloud()); `~processing_time_ms` (std_msgs/Float64, callback entry to publish of
/// the outputs; published only while it has subscribers; not watched by the lazy subscription).
/// Diagnostics (diagnostic_updater, /diagnostics, status "NODELET_NAME: METHOD ground filter"):
/// input/output rate, processing time mean/max, drop counts by reason, NaN/Inf points, points
/// out of the working volume, backend fallbacks and the backend in use, input clouds lost before
/// the callback (estimated from seq / stamp gaps: InputGapCounter) and how busy the filter is;
/// WARN while clouds are dropped or lost, the filter cannot keep up or the stream is irregular.
///
/// Working volume (dynamic_reconfigure `max_range` and `min_range`, every leaf; private
/// parameter `~body_box`, a list [xmin, xmax, ymin, ymax, zmin, zmax] in the input frame, read
/// at start, empty = off): each filter object is wrapped in a WorkingVolumeFilter centred on the
/// sensor origin (the input frame's origin, or its pose in the gravity frame); points farther
/// than max_range, beyond the hard limit, nearer than min_range or inside the body box are
/// published as non-ground one by one and counted; the rest of the cloud is filtered as usual.
///
/// Parameters are checked at start: an unknown private key, a value of the wrong type or out of
/// the .cfg range is refused with one error naming the key (removed from the parameter server,
/// so the default stays), instead of being ignored or clamped.
///
/// Start-up: the first filter object is built in onInit(), before the input is subscribed, so
/// no cloud is ever dropped for want of a filter; a filter that fails on a cloud publishes it
/// all as non-ground.
///
/// Bad streams never stop the nodelet: input messages whose bytes are no PointCloud2 (e.g. a bag
/// holding other messages on the cloud topic) are dropped before any allocation; a frame_id
/// that changes or a stamp that goes back (a bag loop) is processed as usual; each gives a
/// throttled warning and is counted.
class GroundFilterNodelet : public nodelet_topic_tools::NodeletLazy {
 public:
  /// \brief Builds a new filter object from an already validated parameter set.
  using FilterFactory = std::function<std::unique_ptr<GroundFilter>()>;

  GroundFilterNodelet();
  ~GroundFilterNodelet() override;

  /// \brief Counters since start (see NodeletMonitor).
  using Counters = NodeletMonitor::Counters;

 protected:
  /// \brief Sets up node handles, outputs, the leaf (onInitFilter), builds the first filter
  ///        object and subscribes (lazily): a cloud arriving at once is filtered, not dropped.
  void onInit() final;

  /// \brief Leaf hook, called from onInit() before the input is subscribed: start the
  ///        dynamic_reconfigure server; its first callback must call setFilterFactory().
  virtual void onInitFilter() = 0;

  /// \brief Method name for logs ("voxel", "normal").
  virtual std::string methodName() const = 0;

  /// \brief The leaf's own private parameters (its .cfg), checked at start with the base's.
  virtual std::vector<ParamCheck> leafParams() const = 0;

  /// \brief `~body_box` as read at start (empty = off; validated with the volume).
  const std::vector<double>& bodyBox() const { return body_box_; }

  /// \brief Installs a new filter configuration (thread-safe; takes effect on the next cloud).
  /// \param volume working volume around the sensor origin (validated by the caller).
  /// \param description one line for the log, e.g. "voxel_size=0.1 ...".
  void setFilterFactory(FilterFactory factory, const WorkingVolume& volume,
                        const std::string& description);

  /// \brief Logs a refused parameter set (NODELET_ERROR) and counts it.
  void reportRejectedConfig(const std::string& what);

  void subscribe() override;
  void unsubscribe() override;
  /// \brief Runs once after onInit(): starts the timers, subscribes the input if an output was
  /// subscribed while onInit() ran (callbacks queued then are lost with nodelet 1.10.0).
  void afterInit();

  /// \brief Counters for logs and diagnostics.
  const Counters& counters() const { return monitor_.counters(); }

  /// \brief Installs a validated obstacle band of ~obstacles (height above ground).
  void setObstacleBand(const ObstacleBand& band) { hag_.setBand(band); }

 private:
  /// One installed configuration; its address identifies it, so the cloud callback can tell
  /// when its filter object is stale.
  struct FilterConfig {
    FilterFactory make;
    WorkingVolume volume;
    std::string description;
  };
  /// A valid cloud waiting for its transform to the gravity frame.
  struct PendingCloud {
    sensor_msgs::PointCloud2ConstPtr msg;
    CloudLayout layout;
    ros::WallTime deadline;                    // dropped when its transform is still missing then
    std::chrono::steady_clock::time_point t0;  // arrival (processing time counts the wait)
  };
  void cloudCallback(const sensor_msgs::PointCloud2ConstPtr& msg);
  // Filters and publishes one valid cloud (to_gravity: null = classify in the input frame).
  void processCloud(const sensor_msgs::PointCloud2ConstPtr& msg, const CloudLayout& layout,
                    const Eigen::Isometry3d* to_gravity, std::chrono::steady_clock::time_point t0);
  // Processes the queued clouds whose transform has arrived, in order; drops the expired ones;
  // stops at the first that may still wait (the timer tries again).
  void drainPending();
  // Builds the filter object of the installed configuration when it changed (process_mutex_).
  void updateFilter();
  // Publishes one processed cloud and records its counts, time and backend.
  void publish(const ProcessedCloud& out, double ms);
  void logRejected(CloudRejectReason reason, const std::string& message);
  // Counts one stream event in `counter` and warns "<method>: <what> (N so far)<then>" when
  // logNow(slot) allows it.
  void countAndWarn(std::atomic<std::uint64_t>* counter, int slot, const std::string& what,
                    const char* then);
  // Counts and warns about frame_id changes and stamps going back between consecutive clouds.
  void checkStream(const std_msgs::Header& header);
  // An input message that is no PointCloud2 (see CloudSubscriptionHelper).
  void onNotCloud(const std::string& what, const std::string& publisher);
  // True once the leaf installed a filter configuration (diagnostics: ERROR without one).
  bool haveConfig();
  // Refuses unknown / mistyped / out-of-range private parameters (see the class comment).
  void checkParams();

  ros::Subscriber sub_input_;
  ros::Publisher pub_ground_;
  ros::Publisher pub_nonground_;
  ros::Publisher pub_time_;
  ros::Publisher pub_labeled_;
  int queue_size_ = 3;
  std::vector<double> body_box_;  // ~body_box, empty = off

  std::unique_ptr<GravityTransform> gravity_;  // null: classify in the input frame
  std::mutex pending_mutex_;                   // guards pending_
  std::deque<PendingCloud> pending_;           // clouds waiting for their transform
  std::mutex drain_mutex_;                     // one drainPending() at a time (keeps the order)
  ros::WallTimer tf_retry_timer_;              // runs drainPending() while clouds wait

  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostic_timer_;
  ros::WallTimer trim_timer_;        // malloc_trim (glibc) every ~malloc_trim_period
  ros::WallTimer after_init_timer_;  // one shot: afterInit()

  NodeletMonitor monitor_;  // counters, log throttles, diagnostics

  std::mutex config_mutex_;  // guards config_ (set by reconfigure, read by the cloud callback)
  std::shared_ptr<const FilterConfig> config_;

  // The filter and its buffers; the mutex covers callbacks of an old and a new subscription
  // overlapping after unsubscribe()/subscribe().
  std::mutex process_mutex_;
  std::shared_ptr<const FilterConfig> filter_config_;
  std::unique_ptr<WorkingVolumeFilter> filter_;
  CloudProcessingBuffers buffers_;
  std::string logged_note_;  // last backend note written to the log
  HagOutputs hag_;           // height above ground: fields, ~ground_surface, ~obstacles
};

/// \brief A leaf's parameter plumbing, shared by every filter nodelet: a dynamic_reconfigure
///        server of `Config` whose accepted sets become `Filter(Params)`. A set that passes the
///        .cfg ranges but not `Params::validate()` is refused: the last good set stays in use and
///        is reported back to the client (the .cfg defaults when the first set is refused).
template <typename Config, typename Params, typename Filter>
class ReconfigurableFilterNodelet : public GroundFilterNodelet {
 protected:
  /// \brief Called with every accepted set before it is installed (e.g. a backend warning).
  virtual void onParamsAccepted(const Params& /*params*/) {}
  std::string methodName() const override { return Params::method(); }

  std::vector<ParamCheck> leafParams() const override {
    std::vector<ParamCheck> out;
    const Config lo = Config::__getMin__(), hi = Config::__getMax__();
    for (const auto& desc : Config::__getParamDescriptions__()) {
      ParamCheck c;
      c.name = desc->name;
      if (desc->type == "double" || desc->type == "int") {
        c.type = desc->type == "int" ? ParamCheck::Type::kInt : ParamCheck::Type::kDouble;
        boost::any a, b;
        desc->getValue(lo, a);
        desc->getValue(hi, b);
        c.ranged = true;
        c.min = desc->type == "int" ? boost::any_cast<int>(a) : boost::any_cast<double>(a);
        c.max = desc->type == "int" ? boost::any_cast<int>(b) : boost::any_cast<double>(b);
      } else {
        c.type = desc->type == "bool" ? ParamCheck::Type::kBool : ParamCheck::Type::kString;
      }
      out.push_back(c);
    }
    return out;
  }

  void onInitFilter() override {
    server_ = std::make_unique<dynamic_reconfigure::Server<Config>>(*pnh_);
    // The server calls back at once with the parameter-server values: that installs the filter.
    server_->setCallback([this](Config& config, uint32_t level) { reconfigure(config, level); });
  }

 private:
  void reconfigure(Config& config, uint32_t /*level*/) {
    // Every cfg field onto the params struct through its table (no validation).
    Params params = paramsFromConfigTable<Params>(config);
    WorkingVolume volume;
    volume.max_range = config.max_range;
    volume.min_range = config.min_range;
    volume.body_box = bodyBox();
    ObstacleBand band{config.obstacle_min_height, config.obstacle_max_height};
    try {
      params.validate();
      volume.validate();
      band.validate();
    } catch (const std::invalid_argument& e) {
      reportRejectedConfig(e.what());
      // The server publishes `config` after this returns: show what is really in use.
      if (have_good_) {
        config = last_good_;
        return;
      }
      config = Config::__getDefault__();  // the .cfg defaults are the library's
      params = paramsFromConfigTable<Params>(config);
      volume.max_range = config.max_range;
      volume.min_range = config.min_range;
      band = ObstacleBand{config.obstacle_min_height, config.obstacle_max_height};
      try {
        volume.validate();
      } catch (const std::invalid_argument&) {
        volume.body_box.clear();  // reported at start (checkParams)
      }
    }
    last_good_ = config;
    have_good_ = true;
    onParamsAccepted(params);
    setObstacleBand(band);
    setFilterFactory([params]() { return std::make_unique<Filter>(params); }, volume,
                     params.describe());
  }

  std::unique_ptr<dynamic_reconfigure::Server<Config>> server_;
  Config last_good_;  // reported back when a new set is refused
  bool have_good_ = false;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H
