#ifndef GROUND_FILTER_SRC_NODELETS_GRAVITY_TRANSFORM_H
#define GROUND_FILTER_SRC_NODELETS_GRAVITY_TRANSFORM_H

#include <ros/node_handle.h>
#include <std_msgs/Header.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <Eigen/Geometry>
#include <string>

namespace ground_filter {

/// \brief Transforms into a frame whose z axis points up (`~gravity_frame`), looked up from
///        tf2 without waiting: the nodelet queues a cloud whose transform is not there yet and
///        tries again (GroundFilterNodelet), so no thread blocks on tf.
class GravityTransform {
 public:
  /// \param frame the gravity frame; \param timeout_s wall time a cloud may wait for its
  ///        transform [s] (kept here for the nodelet's queue and its messages).
  GravityTransform(ros::NodeHandle& nh, const std::string& frame, double timeout_s);

  const std::string& frame() const { return frame_; }
  double timeout() const { return timeout_s_; }

  /// \brief Transform frame() <- header.frame_id at header.stamp, one try without waiting;
  ///        false (and the tf2 message in `error`) when there is none yet.
  bool lookup(const std_msgs::Header& header, Eigen::Isometry3d* transform,
              std::string* error) const;

 private:
  std::string frame_;
  double timeout_s_;
  tf2_ros::Buffer buffer_;
  tf2_ros::TransformListener listener_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_GRAVITY_TRANSFORM_H
