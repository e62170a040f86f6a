#include "cloud_pool.h"

#include <atomic>
#include <boost/make_shared.hpp>

namespace ground_filter {

namespace {

// A buffer larger than this for the cloud it is taken for is given up (a rare huge cloud must
// not stay resident), 1 MiB of slack so that clouds of varying size keep theirs.
constexpr std::size_t kSlackBytes = std::size_t{1} << 20;

}  // namespace

sensor_msgs::PointCloud2Ptr CloudPool::take(std::size_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  sensor_msgs::PointCloud2Ptr found;
  for (const sensor_msgs::PointCloud2Ptr& slot : slots_) {
    // 1: only the pool holds it, and only the pool can hand out a new reference (under the
    // lock): no other thread can start using it now. The fence orders our writes after the
    // last holder's reads (its release of the count).
    if (slot.use_count() != 1) continue;
    std::atomic_thread_fence(std::memory_order_acquire);
    // Every idle slot, not only the one taken: after a few huge clouds the others would keep
    // their buffers until the pool goes idle.
    if (slot->data.capacity() > 2 * bytes + kSlackBytes) {
      std::vector<std::uint8_t>().swap(slot->data);
    }
    if (!found) found = slot;
  }
  if (found) {
    ++reused_;
    return found;
  }
  ++made_;
  auto msg = boost::make_shared<sensor_msgs::PointCloud2>();
  if (slots_.size() < max_slots_) slots_.push_back(msg);
  return msg;
}

sensor_msgs::PointCloud2Ptr takeCloud(CloudPool* pool, std::size_t bytes) {
  return pool ? pool->take(bytes) : boost::make_shared<sensor_msgs::PointCloud2>();
}

void CloudPool::clear() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<sensor_msgs::PointCloud2Ptr> kept;
  for (sensor_msgs::PointCloud2Ptr& slot : slots_) {
    if (slot.use_count() != 1) kept.push_back(std::move(slot));
  }
  slots_.swap(kept);
}

std::size_t CloudPool::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return slots_.size();
}

std::size_t CloudPool::reused() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return reused_;
}

std::size_t CloudPool::made() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return made_;
}

}  // namespace ground_filter
