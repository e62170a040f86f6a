#ifndef GROUND_FILTER_SRC_CORE_COMMON_THREADS_TIMING_H
#define GROUND_FILTER_SRC_CORE_COMMON_THREADS_TIMING_H

#include <chrono>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ground_filter {

/// \brief The clock of every stage timing in the core.
using Clock = std::chrono::steady_clock;

/// \brief Milliseconds since `t0` (stage and total timings in FilterStats).
inline double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// \brief The `threads` parameter resolved: a positive value as given; 0 = OpenMP's default
///        team size (every core, unless OMP_NUM_THREADS says otherwise); 1 without OpenMP.
inline int resolveThreads(int threads) {
  if (threads > 0) return threads;
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_THREADS_TIMING_H
