#ifndef GROUND_FILTER_SRC_NODELETS_INPUT_REPORTER_H
#define GROUND_FILTER_SRC_NODELETS_INPUT_REPORTER_H

#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>

#include <atomic>
#include <cstdint>
#include <string>

#include "nodelet_monitor.h"
#include "point_cloud2.h"

namespace ground_filter {

/// \brief What goes wrong on a filter nodelet's input, counted in the monitor and logged
///        (throttled per kind) under the nodelet's name: malformed clouds, messages that are no
///        PointCloud2, clouds without a transform to the gravity frame, frame_id changes, stamps
///        going back and clouds lost before the callback.
class InputReporter {
 public:
  /// \param name the nodelet's name (its log lines go out under it); \param method for logs;
  /// \param topic the resolved input topic; \param queue_size `~queue_size` (named in logs).
  InputReporter(const std::string& name, const std::string& method, const std::string& topic,
                int queue_size, NodeletMonitor* monitor);

  /// \brief Compares a cloud's header with the previous one's: frame_id changes, stamps going
  ///        back, clouds lost before the callback (seq / stamp gaps).
  void checkStream(const std_msgs::Header& header);
  /// \brief A cloud checkPointCloud2() refused.
  void rejected(CloudRejectReason reason, const std::string& why);
  /// \brief An input message that is no PointCloud2 (see CloudSubscriptionHelper).
  void notCloud(const std::string& what, const std::string& publisher);
  /// \brief A cloud dropped for want of its transform into `gravity_frame`.
  void noTransform(const sensor_msgs::PointCloud2& cloud, const std::string& gravity_frame,
                   const std::string& why);

  /// \brief The nodelet's name: the NODELET_* log macros use it.
  const std::string& getName() const { return name_; }

 private:
  // Counts one event in `counter` and warns "<method>: <what> (N so far)<then>" when the
  // monitor's throttle of `slot` allows it.
  void countAndWarn(std::atomic<std::uint64_t>* counter, int slot, const std::string& what,
                    const char* then);

  std::string name_;
  std::string method_;
  std::string topic_;
  int queue_size_;
  NodeletMonitor* monitor_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_INPUT_REPORTER_H
