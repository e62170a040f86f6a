// Stage 1b of the normal filter: the sampled points (sample.h).

#include "normal/sample.h"

#include <algorithm>

namespace ground_filter {
namespace normal {

std::size_t SampleStage::gather(const float* xyz, std::size_t len, int stride) {
  const std::size_t s = static_cast<std::size_t>(std::max(1, stride));
  const std::size_t m = (len + s - 1) / s;
  xyz_.resize(3 * m);
  for (std::size_t j = 0; j < m; ++j) std::copy_n(xyz + 3 * (j * s), 3, &xyz_[3 * j]);
  candidate_.assign(m, 0);
  voted_.assign(m, 0);
  return m;
}

void SampleStage::spread(std::size_t len, int stride, std::uint8_t* voted) const {
  // A point between two sampled points is voted when either of them is: a voted point only
  // feeds the RANSAC plane, which drops outliers by their distance, while too few voted points
  // leave a sparse tile to the cloud-wide plane.
  const std::size_t s = static_cast<std::size_t>(std::max(1, stride));
  const std::size_t last = voted_.empty() ? 0 : voted_.size() - 1;
  for (std::size_t i = 0; i < len; ++i) {
    const std::size_t j = i / s;
    voted[i] = i % s == 0 ? voted_[j] : (voted_[j] | voted_[std::min(j + 1, last)]);
  }
}

}  // namespace normal
}  // namespace ground_filter
