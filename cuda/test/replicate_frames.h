// Large test clouds for the GPU tests and the benchmark: scan frames repeated side by side.
#ifndef GROUND_FILTER_CUDA_TEST_REPLICATE_FRAMES_H
#define GROUND_FILTER_CUDA_TEST_REPLICATE_FRAMES_H

#include <cstddef>
#include <vector>

namespace gf_test {

/// \brief `n` packed x y z points: `frames` (packed x y z each, at least one) cycled, copy t
///        shifted by 200 m steps on a 7-wide x/y grid so that copies do not overlap.
inline std::vector<float> replicateFrames(const std::vector<std::vector<float>>& frames,
                                          std::size_t n) {
  std::vector<float> xyz;
  if (frames.empty()) return xyz;
  xyz.reserve(3 * n);
  for (int t = 0; xyz.size() < 3 * n; ++t) {
    const auto& f = frames[t % frames.size()];
    const float ox = 200.f * static_cast<float>(t % 7), oy = 200.f * static_cast<float>(t / 7);
    for (std::size_t i = 0; i < f.size() / 3 && xyz.size() < 3 * n; ++i) {
      xyz.insert(xyz.end(), {f[3 * i] + ox, f[3 * i + 1] + oy, f[3 * i + 2]});
    }
  }
  return xyz;
}

}  // namespace gf_test

#endif  // GROUND_FILTER_CUDA_TEST_REPLICATE_FRAMES_H
