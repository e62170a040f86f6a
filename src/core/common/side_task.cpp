#include "common/side_task.h"

namespace ground_filter {

SideTask::~SideTask() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_.notify_one();
  thread_.join();
}

void SideTask::startRaw(Task task, void* ctx) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    task_ = task;
    ctx_ = ctx;
    busy_ = true;
    error_ = nullptr;
  }
  if (!thread_.joinable()) {
    thread_ = std::thread([this] { loop(); });
  } else {
    start_.notify_one();
  }
}

void SideTask::wait() {
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return !busy_; });
  if (error_) {
    std::exception_ptr e = error_;
    error_ = nullptr;
    std::rethrow_exception(e);
  }
}

void SideTask::loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    start_.wait(lock, [this] { return stop_ || task_ != nullptr; });
    if (stop_) return;
    const Task task = task_;
    void* ctx = ctx_;
    task_ = nullptr;
    lock.unlock();
    std::exception_ptr error;
    try {
      task(ctx);
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    error_ = error;
    busy_ = false;
    done_.notify_one();
  }
}

}  // namespace ground_filter
