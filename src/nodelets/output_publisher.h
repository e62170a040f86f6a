#ifndef GROUND_FILTER_SRC_NODELETS_OUTPUT_PUBLISHER_H
#define GROUND_FILTER_SRC_NODELETS_OUTPUT_PUBLISHER_H

#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <ros/time.h>

#include <functional>
#include <string>

#include "hag_outputs.h"
#include "nodelet_monitor.h"
#include "point_cloud2.h"

namespace ground_filter {

/// \brief The outputs of a filter nodelet, `~ground`, `~nonground`, `~labeled` (lazy) and
///        `~processing_time_ms`, and what publishing one cloud records: counters, the monitor's
///        per-cloud entries, throttled logs of filter errors, fallbacks and far points.
///
/// The one place where a filtered cloud goes out: an extra output is advertised in advertise()
/// and published in publish() from what ProcessedCloud (and HagClouds: height above ground)
/// carries.
class OutputPublisher {
 public:
  /// \brief Advertises a lazy PointCloud2 output (NodeletLazy::advertise(): its subscribers
  ///        start the input subscription).
  using AdvertiseLazy = std::function<ros::Publisher(const std::string& topic)>;

  /// \param name the nodelet's name (its log lines go out under it); \param method for logs.
  OutputPublisher(const std::string& name, const std::string& method, NodeletMonitor* monitor);

  /// \brief Advertises every output; `pnh` is the nodelet's private node handle.
  void advertise(ros::NodeHandle& pnh, const AdvertiseLazy& lazy);

  /// \brief True while `~labeled` has subscribers (only then is it built).
  bool wantLabeled() const { return pub_labeled_.getNumSubscribers() > 0; }

  /// \brief Height above ground: its parameters, ~ground_surface and ~obstacles.
  HagOutputs& hag() { return hag_; }

  /// \brief Publishes one processed cloud (and its height-above-ground clouds) and records its
  ///        counts, time [ms] and backend.
  void publish(const ProcessedCloud& out, const HagClouds& hag, double ms);

  /// \brief The nodelet's name: the NODELET_* log macros use it.
  const std::string& getName() const { return name_; }

 private:
  std::string name_;
  std::string method_;
  NodeletMonitor* monitor_;
  ros::Publisher pub_ground_;
  ros::Publisher pub_nonground_;
  ros::Publisher pub_labeled_;
  ros::Publisher pub_time_;
  std::string logged_note_;       // NodeletMonitor::noteKind() of the last note written to the log
  std::string note_kind_;         // the same of this cloud's note (capacity kept)
  ros::WallTime note_logged_at_;  // when logged_note_ was last written
  HagOutputs hag_;                // height above ground: fields, ~ground_surface, ~obstacles
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_OUTPUT_PUBLISHER_H
