// Stand-in (see rclcpp/rclcpp.hpp): patchwork.hpp only names the type in a declaration.
#ifndef GROUND_FILTER_PEERS_STANDIN_POLYGON_STAMPED_HPP
#define GROUND_FILTER_PEERS_STANDIN_POLYGON_STAMPED_HPP
namespace geometry_msgs {
namespace msg {
struct PolygonStamped {};
}  // namespace msg
}  // namespace geometry_msgs
#endif
