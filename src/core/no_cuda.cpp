// The CUDA library's entry points where the package is built without CUDA (compiled instead of
// cuda/: CMakeLists.txt, cmake/gf_core_only.cmake): knn_backend "gpu" runs on the kd-tree and
// says so.

#include <memory>
#include <string>

#include "knn/knn_backend.h"
#include "normal/filter_executor.h"

namespace ground_filter {

namespace {
const char kNotBuilt[] = "GPU backend not available: built without CUDA";
}  // namespace

bool gpuKnnAvailable(std::string* note) {
  if (note) *note = kNotBuilt;
  return false;
}

std::unique_ptr<KnnBackend> makeGpuKnnBackend(std::unique_ptr<KnnBackend> /*fallback*/,
                                              std::string* note) {
  if (note) *note = kNotBuilt;
  return nullptr;
}

std::unique_ptr<NormalFilterExecutor> makeGpuNormalExecutor(
    const NormalGroundFilterParams& /*params*/, double /*min_abs_nz*/) {
  return nullptr;
}

}  // namespace ground_filter
