// Stand-in (see rclcpp.hpp): patchwork.hpp includes it but uses nothing of it.
#include "rclcpp/rclcpp.hpp"
