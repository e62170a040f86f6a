// Private to the voxel filter: fork-join over a few threads that sleep (not spin) when idle.
#ifndef GROUND_FILTER_SRC_CORE_VOXEL_WORKER_POOL_H
#define GROUND_FILTER_SRC_CORE_VOXEL_WORKER_POOL_H

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace ground_filter {
namespace voxel {

/// \brief Runs fn(t, c) for every chunk c < chunks on up to `threads` threads (t: the thread's
///        index, the caller is 0) and returns when all chunks are done.
///
/// Chunks are claimed one at a time, so a worker that the OS does not schedule soon (a loaded
/// machine) costs nothing: the caller takes its chunks. Workers start on first use and sleep on
/// a condition variable between jobs (OpenMP's spinning workers took the core from the serial
/// stages: a 240 k-point scan went from 22 to 69 ms with two threads on the loaded 2-core
/// machine). No allocation after the first job of a given thread count. Results must not depend
/// on which thread runs a chunk.
class WorkerPool {
 public:
  WorkerPool() = default;
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;
  ~WorkerPool();

  /// \brief fn(int t, int chunk) for every chunk; threads <= 1 runs them all inline.
  template <typename Fn>
  void run(int threads, int chunks, Fn&& fn) {
    if (threads <= 1 || chunks <= 1) {
      for (int c = 0; c < chunks; ++c) fn(0, c);
      return;
    }
    using F = typename std::remove_reference<Fn>::type;
    runRaw(
        threads, chunks, [](void* ctx, int t, int c) { (*static_cast<F*>(ctx))(t, c); }, &fn);
  }

 private:
  using Task = void (*)(void*, int, int);
  void runRaw(int threads, int chunks, Task task, void* ctx);
  void work(int t, std::uint64_t seen);
  /// Claims the next chunk of job `gen`; false when that job has no chunk left (or is over).
  bool claim(std::uint32_t gen, std::uint32_t chunks, std::uint32_t* chunk);
  void finishChunk(std::uint32_t chunks);

  std::vector<std::thread> workers_;  // worker i is thread i + 1
  std::mutex mutex_;
  std::condition_variable start_, done_;
  // The current job (written under mutex_ before its generation is published).
  Task task_ = nullptr;
  void* ctx_ = nullptr;
  std::uint32_t chunks_ = 0;
  std::uint32_t generation_ = 0;
  std::atomic<std::uint64_t> next_{0};  // generation << 32 | next chunk
  std::atomic<std::uint32_t> done_chunks_{0};
  bool stop_ = false;
};

}  // namespace voxel
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_VOXEL_WORKER_POOL_H
