// Stand-in (see rclcpp/rclcpp.hpp): patchwork.hpp includes it but converts no message.
#include <pcl/point_cloud.h>
