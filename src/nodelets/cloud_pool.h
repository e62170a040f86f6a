#ifndef GROUND_FILTER_SRC_NODELETS_CLOUD_POOL_H
#define GROUND_FILTER_SRC_NODELETS_CLOUD_POOL_H

#include <sensor_msgs/PointCloud2.h>

#include <cstddef>
#include <mutex>
#include <vector>

namespace ground_filter {

/// \brief PointCloud2 messages kept from cloud to cloud, so that a stream of large clouds does
///        not allocate, page-fault and zero its buffers anew for every cloud.
///
/// A cloud of 240 k points is about 6.5 MB in and 6.5 MB out. Allocated afresh per cloud (glibc
/// maps every block above its mmap threshold, 1 MiB in the launch files), each of those bytes is
/// a new page to fault in and to zero before it is written: on a 2-core paravirtualised AMD EPYC
/// this took more of the manager's CPU than the filter (docs/ros_integration.md, "A robot's
/// load"). A slot is handed out only while nobody else holds it (use_count() is 1: roscpp has
/// sent it and no subscriber in the process keeps it); otherwise take() makes a new message,
/// pooled while there are fewer than `slots`, else not pooled. Memory comes back: a slot whose
/// buffer is far larger than what it is taken for (after a rare huge cloud) gives it up, and
/// clear() frees every idle slot (the nodelets call it when no cloud came for a trim period).
/// Thread-safe.
class CloudPool {
 public:
  /// \brief At most `slots` messages are kept.
  explicit CloudPool(std::size_t slots = 3) : max_slots_(slots) {}

  /// \brief A message that nobody else holds, for a cloud of about `bytes` of data: its fields
  ///        are the last cloud's (the caller sets every one), its data buffer's capacity kept
  ///        unless it exceeds 2 * bytes + 1 MiB (then freed, in every idle slot).
  sensor_msgs::PointCloud2Ptr take(std::size_t bytes);

  /// \brief Frees the slots nobody else holds (messages still held elsewhere stay pooled).
  void clear();

  /// \brief Messages pooled now (held elsewhere or not).
  std::size_t size() const;

  /// \brief How many take() calls reused a pooled message, and how many made a new one.
  std::size_t reused() const;
  std::size_t made() const;

 private:
  std::size_t max_slots_;
  mutable std::mutex mutex_;
  std::vector<sensor_msgs::PointCloud2Ptr> slots_;
  std::size_t reused_ = 0, made_ = 0;
};

/// \brief `pool->take(bytes)`, or a new message where `pool` is null (callers without a pool:
///        tests, the fuzz target).
sensor_msgs::PointCloud2Ptr takeCloud(CloudPool* pool, std::size_t bytes);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_CLOUD_POOL_H
