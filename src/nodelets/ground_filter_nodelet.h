#ifndef GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H

#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet_topic_tools/nodelet_lazy.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "buffer_release.h"
#include "cloud_pool.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/working_volume.h"
#include "input_reporter.h"
#include "nodelet_monitor.h"
#include "output_publisher.h"
#include "param_check.h"
#include "point_cloud2.h"
#include "tf_wait_queue.h"

namespace ground_filter {

/// \brief Base of the ground filter nodelets: `~input` (sensor_msgs/PointCloud2) is split into
///        `~ground` and `~nonground` (and `~labeled`), subscribed lazily.
///
/// A leaf only builds its filter: in onInitFilter() it starts its dynamic_reconfigure server,
/// whose callback validates the parameters and calls setFilterFactory(). Topics, private
/// parameters, diagnostics and behaviour on bad input: docs/ros_integration.md.
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
  void setObstacleBand(const ObstacleBand& band) { outputs_->hag().setBand(band); }

 private:
  /// One installed configuration; its address identifies it, so the cloud callback can tell
  /// when its filter object is stale.
  struct FilterConfig {
    FilterFactory make;
    WorkingVolume volume;
    std::string description;
  };
  void cloudCallback(const sensor_msgs::PointCloud2ConstPtr& msg);
  // Filters and publishes one valid cloud (to_gravity: null = classify in the input frame).
  void processCloud(const sensor_msgs::PointCloud2ConstPtr& msg, const CloudLayout& layout,
                    const Eigen::Isometry3d* to_gravity, std::chrono::steady_clock::time_point t0);
  // Builds the filter object of the installed configuration when it changed (process_mutex_).
  void updateFilter();
  // Starts the diagnostics and the malloc_trim timer (not yet running).
  void setUpDiagnostics();
  // True once the leaf installed a filter configuration (diagnostics: ERROR without one).
  bool haveConfig();
  // Frees the pooled messages nobody holds (idle, or after a rare large cloud).
  void clearPools();
  // Refuses unknown / mistyped / out-of-range private parameters, reads ~body_box.
  void checkParams();

  // Messages reused from cloud to cloud (cloud_pool.h): the deserialised input and the two
  // outputs. First: the subscription and the timers that use them go before them.
  CloudPool input_pool_;
  OutputPools output_pools_;
  std::atomic<bool> active_{false};  // a cloud came since the last trim timer tick

  ros::Subscriber sub_input_;
  int queue_size_ = 3;
  std::vector<double> body_box_;  // ~body_box, empty = off

  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostic_timer_;
  ros::WallTimer trim_timer_;        // malloc_trim (glibc) every ~malloc_trim_period
  ros::WallTimer after_init_timer_;  // one shot: afterInit()

  NodeletMonitor monitor_;  // counters, log throttles, diagnostics
  std::unique_ptr<InputReporter> input_;
  std::unique_ptr<OutputPublisher> outputs_;

  std::mutex config_mutex_;  // guards config_ (set by reconfigure, read by the cloud callback)
  std::shared_ptr<const FilterConfig> config_;

  // The filter and its buffers; the mutex covers callbacks of an old and a new subscription
  // overlapping after unsubscribe()/subscribe().
  std::mutex process_mutex_;
  std::shared_ptr<const FilterConfig> filter_config_;
  std::unique_ptr<WorkingVolumeFilter> filter_;
  CloudProcessingBuffers buffers_;
  BufferReleasePolicy release_;  // drops filter_ and buffers_ after a rare large cloud

  // Last: destroyed first, so no cloud comes out of it into a half-destroyed nodelet.
  std::unique_ptr<TfWaitQueue> tf_wait_;  // null: classify in the input frame
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_GROUND_FILTER_NODELET_H
