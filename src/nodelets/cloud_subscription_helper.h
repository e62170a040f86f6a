#ifndef GROUND_FILTER_SRC_NODELETS_CLOUD_SUBSCRIPTION_HELPER_H
#define GROUND_FILTER_SRC_NODELETS_CLOUD_SUBSCRIPTION_HELPER_H

#include <ros/subscription_callback_helper.h>
#include <sensor_msgs/PointCloud2.h>

#include <functional>
#include <string>
#include <typeinfo>

#include "cloud_pool.h"

namespace ground_filter {

/// \brief Subscription helper of ~input: deserialises sensor_msgs/PointCloud2 like roscpp's own
/// helper, but checks the bytes first, so that a message that is no PointCloud2 (a bag replaying
/// other messages on the cloud topic puts their bytes on the PointCloud2 connection) is counted and
/// reported by the nodelet instead of failing inside roscpp unseen, or allocating gigabytes.
/// It reports PointCloud2's type_info, so same-process PointCloud2 publishers keep zero-copy
/// delivery (roscpp then hands over the shared pointer and never calls deserialize()). The
/// subscription itself stays typed: a "*" subscription would take the md5sum of whichever
/// publisher connects first and could then refuse the real PointCloud2 publishers.
class CloudSubscriptionHelper : public ros::SubscriptionCallbackHelper {
 public:
  using CloudCallback = std::function<void(const sensor_msgs::PointCloud2ConstPtr&)>;
  using ProblemCallback = std::function<void(const std::string& what, const std::string& from)>;

  /// \param pool where deserialised messages come from (reused buffers); null: new ones.
  CloudSubscriptionHelper(CloudCallback on_cloud, ProblemCallback on_not_cloud,
                          CloudPool* pool = nullptr)
      : on_cloud_(std::move(on_cloud)), on_not_cloud_(std::move(on_not_cloud)), pool_(pool) {}

  /// \brief Checks the bytes, then deserialises; a null pointer (no callback) for bytes that are
  ///        no PointCloud2, reported through the problem callback.
  ros::VoidConstPtr deserialize(
      const ros::SubscriptionCallbackHelperDeserializeParams& params) override;

  void call(ros::SubscriptionCallbackHelperCallParams& params) override {
    on_cloud_(
        boost::static_pointer_cast<const sensor_msgs::PointCloud2>(params.event.getConstMessage()));
  }

  const std::type_info& getTypeInfo() override { return typeid(sensor_msgs::PointCloud2); }
  bool isConst() override { return true; }
  bool hasHeader() override { return true; }

 private:
  CloudCallback on_cloud_;
  ProblemCallback on_not_cloud_;
  CloudPool* pool_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_CLOUD_SUBSCRIPTION_HELPER_H
