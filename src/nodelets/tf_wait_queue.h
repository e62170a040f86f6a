#ifndef GROUND_FILTER_SRC_NODELETS_TF_WAIT_QUEUE_H
#define GROUND_FILTER_SRC_NODELETS_TF_WAIT_QUEUE_H

#include <ros/node_handle.h>
#include <ros/wall_timer.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/message_filter.h>
#include <tf2_ros/transform_listener.h>

#include <Eigen/Geometry>
#include <chrono>
#include <deque>
#include <functional>
#include <mutex>
#include <string>

#include "point_cloud2.h"

namespace ground_filter {

/// \brief Clouds waiting for their transform into the gravity frame (`~gravity_frame`).
///
/// tf2_ros::MessageFilter holds them (at most `queue_size`, the oldest pushed out) and hands
/// each one over once tf2 has its transform; no thread waits. ROS 1's MessageFilter has no time
/// limit, so this class adds `~tf_timeout` (wall time, checked every 5 ms while a cloud waits)
/// and turns every way out into one call: `ready` with the transform, or `dropped` with the
/// reason. Both run on the callback queue of the node handle given (the nodelet's
/// single-threaded one: one cloud at a time, in the order the transforms arrive); add() may be
/// called from any thread.
class TfWaitQueue {
 public:
  using Clock = std::chrono::steady_clock;
  using Ready = std::function<void(const sensor_msgs::PointCloud2ConstPtr&, const CloudLayout&,
                                   const Eigen::Isometry3d& to_gravity, Clock::time_point t0)>;
  using Dropped =
      std::function<void(const sensor_msgs::PointCloud2ConstPtr&, const std::string& why)>;

  /// \param frame the gravity frame; \param timeout_s wall time a cloud may wait [s];
  /// \param queue_size clouds that may wait at once.
  TfWaitQueue(ros::NodeHandle& nh, const std::string& frame, double timeout_s, int queue_size,
              Ready ready, Dropped dropped);
  ~TfWaitQueue();

  const std::string& frame() const { return frame_; }
  double timeout() const { return timeout_s_; }

  /// \brief Takes a valid cloud (`layout` from checkPointCloud2()); `t0` is its arrival.
  void add(const sensor_msgs::PointCloud2ConstPtr& msg, const CloudLayout& layout,
           Clock::time_point t0);

 private:
  struct Waiting {
    sensor_msgs::PointCloud2ConstPtr msg;
    CloudLayout layout;
    Clock::time_point t0;
    ros::WallTime deadline;
  };
  void onReady(const sensor_msgs::PointCloud2ConstPtr& msg);
  void onFailure(const sensor_msgs::PointCloud2ConstPtr& msg, tf2_ros::FilterFailureReason reason);
  void expire();  // the timer: drops the clouds past their deadline
  // Removes `msg` from waiting_; false when it is no longer there (expired, then counted).
  bool take(const sensor_msgs::PointCloud2ConstPtr& msg, Waiting* waiting);
  // Transform frame_ <- header.frame_id at header.stamp, one try; tf2's message in `error`.
  bool lookup(const std_msgs::Header& header, Eigen::Isometry3d* transform,
              std::string* error) const;

  std::string frame_;
  double timeout_s_;
  int queue_size_;
  Ready ready_;
  Dropped dropped_;
  // Clouds in the MessageFilter that have not expired, in arrival order (so expiry pops the
  // front). The filter may still hold expired ones: they are its oldest, pushed out first, and
  // ignored when they come out.
  std::mutex mutex_;  // guards waiting_
  std::deque<Waiting> waiting_;
  tf2_ros::Buffer buffer_;
  tf2_ros::MessageFilter<sensor_msgs::PointCloud2> filter_;
  // Destroyed before the filter: no /tf update calls into a filter being destroyed.
  tf2_ros::TransformListener listener_;
  ros::WallTimer timer_;  // runs expire() while clouds wait
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_TF_WAIT_QUEUE_H
