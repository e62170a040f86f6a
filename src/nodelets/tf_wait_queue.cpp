#include "tf_wait_queue.h"

#include <geometry_msgs/TransformStamped.h>
#include <tf2/exceptions.h>

#include <boost/function.hpp>
#include <cstdio>
#include <utility>
#include <vector>

namespace ground_filter {

namespace {

// tf2 refuses frame ids with a leading '/'; tf2_ros::MessageFilter strips it, so do we.
std::string stripSlash(const std::string& frame) {
  return !frame.empty() && frame[0] == '/' ? frame.substr(1) : frame;
}

}  // namespace

TfWaitQueue::TfWaitQueue(ros::NodeHandle& nh, const std::string& frame, double timeout_s,
                         int queue_size, Ready ready, Dropped dropped)
    : frame_(frame),
      timeout_s_(timeout_s),
      queue_size_(queue_size),
      ready_(std::move(ready)),
      dropped_(std::move(dropped)),
      filter_(buffer_, frame, static_cast<std::uint32_t>(queue_size), nh),
      listener_(buffer_, nh) {
  filter_.registerCallback(boost::function<void(const sensor_msgs::PointCloud2ConstPtr&)>(
      [this](const sensor_msgs::PointCloud2ConstPtr& msg) { onReady(msg); }));
  filter_.registerFailureCallback(
      [this](const sensor_msgs::PointCloud2ConstPtr& msg, tf2_ros::FilterFailureReason reason) {
        onFailure(msg, reason);
      });
  timer_ = nh.createWallTimer(
      ros::WallDuration(0.005), [this](const ros::WallTimerEvent&) { expire(); }, false, false);
}

TfWaitQueue::~TfWaitQueue() { timer_.stop(); }

void TfWaitQueue::add(const sensor_msgs::PointCloud2ConstPtr& msg, const CloudLayout& layout,
                      Clock::time_point t0) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    waiting_.push_back(
        Waiting{msg, layout, t0, ros::WallTime::now() + ros::WallDuration(timeout_s_)});
    timer_.start();  // no-op when running
  }
  filter_.add(msg);  // ready or dropped at once when tf2 can tell already
}

bool TfWaitQueue::take(const sensor_msgs::PointCloud2ConstPtr& msg, Waiting* waiting) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = waiting_.begin(); it != waiting_.end(); ++it) {
    if (it->msg == msg) {
      *waiting = std::move(*it);
      waiting_.erase(it);
      return true;
    }
  }
  return false;
}

void TfWaitQueue::onReady(const sensor_msgs::PointCloud2ConstPtr& msg) {
  Waiting waiting;
  if (!take(msg, &waiting)) return;
  Eigen::Isometry3d to_gravity = Eigen::Isometry3d::Identity();
  std::string why;
  if (lookup(msg->header, &to_gravity, &why)) {
    ready_(msg, waiting.layout, to_gravity, waiting.t0);
  } else {
    dropped_(msg, why);
  }
}

void TfWaitQueue::onFailure(const sensor_msgs::PointCloud2ConstPtr& msg,
                            tf2_ros::FilterFailureReason reason) {
  Waiting waiting;
  if (!take(msg, &waiting)) return;
  std::string why;
  switch (reason) {
    case tf2_ros::filter_failure_reasons::OutTheBack:
      why = "the stamp is older than the tf buffer holds";
      break;
    case tf2_ros::filter_failure_reasons::EmptyFrameID:
      why = "the cloud has no frame_id";
      break;
    default:
      why = "pushed out of the wait queue by " + std::to_string(queue_size_) +
            " newer clouds waiting for theirs (~queue_size), or refused by tf2";
  }
  dropped_(msg, why);
}

void TfWaitQueue::expire() {
  const ros::WallTime now = ros::WallTime::now();
  std::vector<Waiting> expired;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    while (!waiting_.empty() && waiting_.front().deadline <= now) {
      expired.push_back(std::move(waiting_.front()));
      waiting_.pop_front();
    }
    if (waiting_.empty()) timer_.stop();
  }
  for (const Waiting& w : expired) {
    Eigen::Isometry3d unused;
    std::string why;
    if (lookup(w.msg->header, &unused, &why)) why = "it came too late";
    char within[48];
    std::snprintf(within, sizeof(within), "not there within %.3f s: ", timeout_s_);
    dropped_(w.msg, within + why);
  }
}

bool TfWaitQueue::lookup(const std_msgs::Header& header, Eigen::Isometry3d* transform,
                         std::string* error) const {
  try {
    const geometry_msgs::TransformStamped t =
        buffer_.lookupTransform(frame_, stripSlash(header.frame_id), header.stamp);
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
