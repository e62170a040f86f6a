// Stage 1 of the normal filter: compaction of the finite points, grid-column (Morton) order,
// segments.

#include "order.h"

#include <omp.h>

#include <cstring>
#include <limits>

#include "common/radix_sort.h"
#include "cpu_gpu_common.h"
#include "normal/cell_keys.h"

namespace ground_filter {
namespace normal {

std::size_t OrderStage::run(const CloudView& cloud, double cell_size, bool use_segments,
                            int segment_points, int threads, OrderedPoints* out) {
  const std::size_t total = cloud.size();
  raw_xyz_.resize(3 * total);
  raw_source_.resize(total);
  // Compaction per block of points, each into its own place, then the blocks moved down one
  // after the other: the same order as one serial pass. min/max are exact, so the split does
  // not matter.
  const int ct =
      static_cast<int>(std::min<std::size_t>(threads > 0 ? threads : 1, total / 32768 + 1));
  block_count_.assign(static_cast<std::size_t>(ct) + 1, 0);
  const double inf = std::numeric_limits<double>::infinity();
  double min_x = inf, min_y = inf, max_x = -inf, max_y = -inf;
#pragma omp parallel num_threads(ct) reduction(min : min_x, min_y) reduction(max : max_x, max_y)
  {
    const int t = omp_get_thread_num(), nt_run = omp_get_num_threads();
    const std::size_t b = total * t / nt_run, e = total * (t + 1) / nt_run;
    std::size_t kept = b;
    for (std::size_t i = b; i < e; ++i) {
      float* o = &raw_xyz_[3 * kept];
      if (!cloud.get(i, o, o + 1, o + 2)) continue;
      raw_source_[kept++] = static_cast<std::uint32_t>(i);
      min_x = std::min<double>(min_x, o[0]);
      min_y = std::min<double>(min_y, o[1]);
      max_x = std::max<double>(max_x, o[0]);
      max_y = std::max<double>(max_y, o[1]);
    }
    block_count_[t + 1] = kept - b;
#pragma omp barrier
#pragma omp single
    {
      std::size_t dst = 0;
      for (int i = 0; i < nt_run; ++i) {
        const std::size_t src = total * i / nt_run, cnt = block_count_[i + 1];
        if (dst != src) {
          std::memmove(&raw_xyz_[3 * dst], &raw_xyz_[3 * src], 3 * cnt * sizeof(float));
          std::memmove(&raw_source_[dst], &raw_source_[src], cnt * sizeof(std::uint32_t));
        }
        dst += cnt;
      }
      block_count_[0] = dst;
    }
  }
  const std::size_t valid = block_count_[0];
  raw_xyz_.resize(3 * valid);
  raw_source_.resize(valid);
  out->extent = Extent{min_x, min_y, max_x, max_y};
  const std::size_t n = raw_source_.size();
  std::vector<float>& xyz = out->xyz;
  std::vector<std::uint32_t>& source = out->source;
  std::vector<std::pair<std::size_t, std::size_t>>& segments = out->segments;
  xyz.resize(3 * n);
  source.resize(n);
  segments.clear();
  if (n == 0) return 0;
  // Coarsen the ordering grid for very wide clouds so cell indices fit in 32 bits.
  const double cell = std::max(cell_size, out->extent.size() / 4.0e9);
  out->cell = cell;
  keys_.resize(n);
  const int nt = static_cast<int>(std::min<std::size_t>(threads, n / 16384 + 1));
#pragma omp parallel num_threads(nt)
  {
    const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
    const std::size_t parts = static_cast<std::size_t>(omp_get_num_threads());
    columnKeysOf(raw_xyz_.data(), n * t / parts, n * (t + 1) / parts, min_x, min_y, 1.0 / cell,
                 keys_.data());
  }
  radixSortByKey(keys_, &order_, &sort_scratch_, threads);
  // Plain pointers and three stores: through the vectors GCC cannot rule out that they overlap
  // and calls memmove for every point's 12 bytes.
  const std::uint32_t* const ord = order_.data();
  const float* const from = raw_xyz_.data();
  const std::uint32_t* const from_source = raw_source_.data();
  float* const to = xyz.data();
  std::uint32_t* const to_source = source.data();
#pragma omp parallel for num_threads(nt) schedule(static)
  for (std::int64_t j = 0; j < static_cast<std::int64_t>(n); ++j) {
    const std::size_t s = ord[j];
    const float x = from[3 * s], y = from[3 * s + 1], z = from[3 * s + 2];
    to[3 * j] = x;
    to[3 * j + 1] = y;
    to[3 * j + 2] = z;
    to_source[j] = from_source[s];
  }
  // Segments of at most segment_points, cut at column borders (whole cloud when disabled).
  if (use_segments) {
    const std::size_t seg = static_cast<std::size_t>(segment_points);
    std::size_t begin = 0;
    while (begin < n) {
      std::size_t end = std::min(n, begin + seg);
      if (end < n) {
        std::size_t cut = end;
        while (cut > begin + 1 && keys_[order_[cut - 1]] == keys_[order_[cut]]) --cut;
        if (cut > begin + 1) end = cut;  // else one column is larger than a segment: split it
      }
      segments.emplace_back(begin, end);
      begin = end;
    }
  } else {
    segments.emplace_back(0, n);
  }
  return n;
}

void OrderStage::fromOrder(const CloudView& cloud, double cell_size, OrderedPoints* out) {
  const std::size_t n = out->source.size();
  out->xyz.resize(3 * n);
  const double inf = std::numeric_limits<double>::infinity();
  double min_x = inf, min_y = inf, max_x = -inf, max_y = -inf;
  for (std::size_t j = 0; j < n; ++j) {
    float* o = &out->xyz[3 * j];
    cloud.get(out->source[j], o, o + 1, o + 2);  // finite: the executor ordered finite points
    min_x = std::min<double>(min_x, o[0]);
    min_y = std::min<double>(min_y, o[1]);
    max_x = std::max<double>(max_x, o[0]);
    max_y = std::max<double>(max_y, o[1]);
  }
  out->extent = Extent{min_x, min_y, max_x, max_y};
  out->cell = std::max(cell_size, out->extent.size() / 4.0e9);  // as run()
  out->segments.assign(1, {0, n});
}

}  // namespace normal
}  // namespace ground_filter
