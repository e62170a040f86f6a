// Stage 1b of the normal filter: the sampled points (sample.h).

#include "normal/sample.h"

#include <algorithm>
#include <cstdint>
#include <utility>

#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace normal {

std::size_t SampleStage::gather(const float* xyz, std::size_t len, int stride, int column_cap,
                                const ColumnGrid& grid, int threads) {
  const std::size_t s = static_cast<std::size_t>(std::max(1, stride));
  index_.clear();
  index_.reserve(len / s + 2);
  auto strided = [&](std::size_t from, std::size_t to) {  // every s-th point of the segment
    for (std::size_t i = (from + s - 1) / s * s; i < to; i += s) {
      index_.push_back(static_cast<std::uint32_t>(i));
    }
  };
  auto column = [&](std::size_t i) {
    return std::make_pair(cellIndex(xyz[3 * i], grid.min_x, grid.inv_cell),
                          cellIndex(xyz[3 * i + 1], grid.min_y, grid.inv_cell));
  };
  // A column of more than L = s * cap points holds two points h <= L / 2 apart at a multiple of
  // h: probing those finds every such column at a cost of 2 / h cell indices a point (vehicle
  // LiDAR scans have none), then its ends are walked.
  const std::size_t cap = static_cast<std::size_t>(std::max(0, column_cap));
  const std::size_t big = s * cap, h = std::max<std::size_t>(1, big / 2);
  std::size_t done = 0;  // points before `done` are decided
  for (std::size_t t = 0; cap > 0 && t + h < len; t += h) {
    if (t < done) continue;
    const auto col = column(t);
    if (column(t + h) != col) continue;
    std::size_t a = t, e = t + h + 1;
    while (a > done && column(a - 1) == col) --a;
    while (e < len && column(e) == col) ++e;
    const std::size_t step = columnSampleStep(e - a, s, cap);
    if (step == 0) continue;  // a column, but not over the cap
    strided(done, a);
    for (std::size_t i = a; i < e; i += step) index_.push_back(static_cast<std::uint32_t>(i));
    done = e;
  }
  strided(done, len);
  const std::size_t m = index_.size();
  index_.push_back(static_cast<std::uint32_t>(len));
  xyz_.resize(3 * m);
  const std::uint32_t* const idx = index_.data();
  float* const to = xyz_.data();
  // In halves on two threads, each mostly reading what it wrote in the column sort (the same
  // static split): a point written on the other core costs a transfer between their caches.
  const int nt = static_cast<int>(std::min<std::size_t>(std::max(threads, 1), m / 16384 + 1));
#pragma omp parallel for num_threads(nt) schedule(static)
  for (std::int64_t jj = 0; jj < static_cast<std::int64_t>(m); ++jj) {
    const std::size_t j = static_cast<std::size_t>(jj);  // three stores, not a memmove (order.cpp)
    const float* const from = xyz + 3 * static_cast<std::size_t>(idx[j]);
    const float x = from[0], y = from[1], z = from[2];
    to[3 * j] = x;
    to[3 * j + 1] = y;
    to[3 * j + 2] = z;
  }
  candidate_.assign(m, 0);
  voted_.assign(m, 0);
  return m;
}

void SampleStage::spread(std::uint8_t* voted) const {
  // A point between two sampled points is voted when either of them is: a voted point only
  // feeds the RANSAC plane, which drops outliers by their distance, while too few voted points
  // leave a sparse tile to the cloud-wide plane.
  const std::size_t m = voted_.size();
  if (m == 0) return;
  // index_[0] is 0: the first column's first point is always sampled.
  for (std::size_t j = 0; j < m; ++j) {
    const std::uint8_t own = voted_[j], between = voted_[j] | voted_[std::min(j + 1, m - 1)];
    voted[index_[j]] = own;
    for (std::size_t i = index_[j] + 1; i < index_[j + 1]; ++i) voted[i] = between;
  }
}

int strideForScanLines(const ScanLines& lines, double max_ratio, int stride) {
  const double r = lines.ratio();
  if (!(max_ratio > 0.0) || !(r > 0.0)) return stride;
  while (stride < kMaxSampleStride && r / stride > max_ratio) {
    stride = doubledStride(stride);
  }
  return stride;
}

}  // namespace normal
}  // namespace ground_filter
