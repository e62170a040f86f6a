// Private to the core: one job at a time on a thread of its own, beside the caller.
#ifndef GROUND_FILTER_SRC_CORE_COMMON_SIDE_TASK_H
#define GROUND_FILTER_SRC_CORE_COMMON_SIDE_TASK_H

#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <type_traits>

namespace ground_filter {

/// \brief Runs one job beside the caller: start(fn) hands fn over, wait() returns when it is
///        done (and rethrows what it threw).
///
/// For host work that fits into the time the caller spends waiting on something else (the GPU
/// pipeline's syncs). The thread starts on first use and sleeps on a condition variable between
/// jobs; no allocation after that. Not thread-safe: one caller.
class SideTask {
 public:
  SideTask() = default;
  SideTask(const SideTask&) = delete;
  SideTask& operator=(const SideTask&) = delete;
  ~SideTask();

  /// \brief Starts fn() on the side thread; fn must outlive the next wait(), which must come
  ///        before the next start().
  template <typename Fn>
  void start(Fn* fn) {
    using F = typename std::remove_reference<Fn>::type;
    startRaw([](void* ctx) { (*static_cast<F*>(ctx))(); }, fn);
  }
  /// \brief Returns when the job of the last start() is done (at once when none is running).
  void wait();

 private:
  using Task = void (*)(void*);
  void startRaw(Task task, void* ctx);
  void loop();

  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  Task task_ = nullptr;  // the job handed over, null once the side thread has taken it
  void* ctx_ = nullptr;
  bool busy_ = false;  // a job handed over and not yet done
  bool stop_ = false;
  std::exception_ptr error_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_SIDE_TASK_H
