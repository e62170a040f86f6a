#include "voxel/worker_pool.h"

namespace ground_filter {
namespace voxel {

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_.notify_all();
  for (std::thread& w : workers_) w.join();
}

bool WorkerPool::claim(std::uint32_t gen, std::uint32_t chunks, std::uint32_t* chunk) {
  std::uint64_t cur = next_.load(std::memory_order_relaxed);
  for (;;) {
    if ((cur >> 32) != gen || (cur & 0xffffffffu) >= chunks) return false;
    if (next_.compare_exchange_weak(cur, cur + 1, std::memory_order_acq_rel)) {
      *chunk = static_cast<std::uint32_t>(cur & 0xffffffffu);
      return true;
    }
  }
}

void WorkerPool::finishChunk(std::uint32_t chunks) {
  if (done_chunks_.fetch_add(1, std::memory_order_acq_rel) + 1 == chunks) {
    std::lock_guard<std::mutex> lock(mutex_);
    done_.notify_all();
  }
}

void WorkerPool::runRaw(int threads, int chunks, Task task, void* ctx) {
  while (static_cast<int>(workers_.size()) < threads - 1) {
    const int t = static_cast<int>(workers_.size()) + 1;
    const std::uint64_t seen = generation_;  // the worker waits for the next job
    workers_.emplace_back([this, t, seen] { work(t, seen); });
  }
  const std::uint32_t n = static_cast<std::uint32_t>(chunks);
  std::uint32_t gen;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    gen = ++generation_;
    task_ = task;
    ctx_ = ctx;
    chunks_ = n;
    done_chunks_.store(0, std::memory_order_relaxed);
    next_.store(static_cast<std::uint64_t>(gen) << 32, std::memory_order_release);
  }
  start_.notify_all();
  std::uint32_t c;
  while (claim(gen, n, &c)) {
    task(ctx, 0, static_cast<int>(c));
    finishChunk(n);
  }
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [&] { return done_chunks_.load(std::memory_order_acquire) == n; });
}

void WorkerPool::work(int t, std::uint64_t seen) {
  for (;;) {
    Task task;
    void* ctx;
    std::uint32_t gen, n;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      gen = generation_;
      task = task_;
      ctx = ctx_;
      n = chunks_;
    }
    std::uint32_t c;
    while (claim(gen, n, &c)) {  // a job that is over has no chunk left: ctx is not used
      task(ctx, t, static_cast<int>(c));
      finishChunk(n);
    }
  }
}

}  // namespace voxel
}  // namespace ground_filter
