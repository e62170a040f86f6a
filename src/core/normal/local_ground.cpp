// Stage 5a of the normal filter: the local ground plane (local_ground.h).

#include "normal/local_ground.h"

#include <algorithm>

#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace normal {

std::size_t LocalGroundStage::run(const std::vector<float>& xyz, const std::int32_t* rows,
                                  const std::uint32_t* points, std::size_t m, int k,
                                  const std::uint32_t* sampled, int min_ground, double max_below,
                                  double max_above, double min_abs_nz, int threads,
                                  std::vector<std::uint8_t>* ground_io) {
  std::vector<std::uint8_t>& ground = *ground_io;
  const std::size_t n = ground.size();
  if (n == 0 || m == 0 || k <= 0 || rows == nullptr) return 0;
  // The sampled points' labels before this stage: every decision reads these only.
  sampled_ground_.resize(m);
  auto at = [sampled](std::size_t j) { return sampledPosition(sampled, j); };
  std::size_t added = 0;
  const int nt = static_cast<int>(std::min<std::size_t>(threads, m / 2048 + 1));
#pragma omp parallel num_threads(nt) reduction(+ : added)
  {
#pragma omp for schedule(static)
    for (std::int64_t j = 0; j < static_cast<std::int64_t>(m); ++j) {
      sampled_ground_[j] = ground[std::min(at(static_cast<std::size_t>(j)), n - 1)];
    }
#pragma omp for schedule(static, 2048)
    for (std::int64_t rr = 0; rr < static_cast<std::int64_t>(m); ++rr) {
      const std::size_t r = static_cast<std::size_t>(rr);
      const std::size_t o = points ? points[r] : r;  // sampled point of this row
      // The points that use this list: the sampled one and those after it up to the next. All of
      // them ground already (about half the rows): nothing to decide, and the list (k indices,
      // the stage's memory traffic) is not read.
      const std::size_t last = std::min(at(o + 1), n);
      std::size_t i0 = at(o);
      while (i0 < last && ground[i0]) ++i0;
      if (i0 == last) continue;
      const std::int32_t* row = rows + r * static_cast<std::size_t>(k);
      // Too few ground neighbours for any point of the row (the fit would refuse it): skip the
      // sums. Most non-ground points (objects, vegetation) end here.
      int count = 0;
      for (int e = 0; e < k && row[e] >= 0; ++e) count += sampled_ground_[row[e]];
      if (count < min_ground) continue;
      for (std::size_t i = i0; i < last; ++i) {
        if (ground[i]) continue;
        const float* q = &xyz[3 * i];
        LocalGroundFit fit;
        for (int e = 0; e < k && row[e] >= 0; ++e) {
          const std::size_t j = static_cast<std::size_t>(row[e]);
          if (!sampled_ground_[j]) continue;
          const float* g = &xyz[3 * at(j)];
          fit.add(static_cast<double>(g[0]) - static_cast<double>(q[0]),
                  static_cast<double>(g[1]) - static_cast<double>(q[1]),
                  static_cast<double>(g[2]) - static_cast<double>(q[2]));
        }
        if (fit.accepts(min_ground, max_below, max_above, min_abs_nz)) {
          ground[i] = 1;
          ++added;
        }
      }
    }
  }
  return added;
}

}  // namespace normal
}  // namespace ground_filter
