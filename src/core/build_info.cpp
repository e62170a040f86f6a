#include "ground_filter/build_info.h"

#include "ground_filter/neighbor_search.h"
#include "simd/simd.h"

namespace ground_filter {

namespace {

std::string compilerName() {
#if defined(__clang__)
  return std::string("Clang ") + __clang_version__;
#elif defined(__GNUC__)
  return std::string("GCC ") + __VERSION__;
#else
  return "unknown compiler";
#endif
}

}  // namespace

BuildInfo buildInfo(bool probe_gpu) {
  BuildInfo info;
  info.simd_level = simd::levelName(simd::active());
  info.simd_best = simd::levelName(simd::best());
  info.cpu_model = simd::cpuModel();
  info.compiler = compilerName();
#if defined(GROUND_FILTER_HAVE_CUDA)
  info.cuda_built = true;
#endif
  std::string cuda = info.cuda_built ? "built" : "not built";
  if (probe_gpu) {
    info.cuda_probed = true;
    info.cuda_available = neighborSearchAvailable("gpu", &info.cuda_note);
    cuda = info.cuda_available ? "yes" : "no (" + info.cuda_note + ")";
  }
  info.summary = simd::describe() + "; " + info.compiler + "; CUDA " + cuda;
  return info;
}

}  // namespace ground_filter
