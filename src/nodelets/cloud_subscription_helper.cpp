#include "cloud_subscription_helper.h"

#include "point_cloud2.h"

namespace ground_filter {

ros::VoidConstPtr CloudSubscriptionHelper::deserialize(
    const ros::SubscriptionCallbackHelperDeserializeParams& params) {
  std::string type, md5, callerid;
  if (params.connection_header) {
    const ros::M_string& h = *params.connection_header;
    auto get = [&h](const char* key) {
      const auto it = h.find(key);
      return it == h.end() ? std::string() : it->second;
    };
    type = get("type");
    md5 = get("md5sum");
    callerid = get("callerid");
  }
  const std::string want_md5 = ros::message_traits::md5sum<sensor_msgs::PointCloud2>();
  if (!md5.empty() && md5 != "*" && md5 != want_md5) {
    on_not_cloud_("a connection of type " + type + " (md5sum " + md5 + ")", callerid);
    return ros::VoidConstPtr();  // roscpp skips the callback for a null message
  }
  std::string why;
  // A reused message: its data buffer is already mapped and sized (no page faults, no zeroing).
  const sensor_msgs::PointCloud2Ptr msg = takeCloud(pool_, params.length);
  if (!deserializePointCloud2(params.buffer, params.length, msg.get(), &why)) {
    on_not_cloud_("bytes that do not decode as a PointCloud2: " + why, callerid);
    return ros::VoidConstPtr();
  }
  return msg;
}

}  // namespace ground_filter
