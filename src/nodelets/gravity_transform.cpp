#include "gravity_transform.h"

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <tf2/exceptions.h>

namespace ground_filter {

GravityTransform::GravityTransform(ros::NodeHandle& nh, const std::string& frame, double timeout_s)
    : frame_(frame), timeout_s_(timeout_s), listener_(buffer_, nh) {}

bool GravityTransform::lookup(const std_msgs::Header& header, Eigen::Isometry3d* transform,
                              std::string* error) const {
  try {
    const geometry_msgs::TransformStamped t =
        buffer_.lookupTransform(frame_, header.frame_id, header.stamp);
    const auto& q = t.transform.rotation;
    const auto& v = t.transform.translation;
    transform->linear() = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
    transform->translation() = Eigen::Vector3d(v.x, v.y, v.z);
    transform->makeAffine();
    return true;
  } catch (const tf2::TransformException& e) {
    *error = e.what();
  }
  return false;
}

}  // namespace ground_filter
