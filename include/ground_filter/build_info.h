#ifndef GROUND_FILTER_BUILD_INFO_H
#define GROUND_FILTER_BUILD_INFO_H

#include <string>

namespace ground_filter {

/// \brief What this build of the library runs with on this machine: for logs and bug reports.
struct BuildInfo {
  std::string simd_level;    ///< SIMD path in force ("portable", "sse", "neon", "avx2", "avx512")
  std::string simd_best;     ///< the highest path this build and CPU run
  std::string cpu_model;     ///< as the OS reports it, or "unknown"
  std::string compiler;      ///< the compiler that built the library, e.g. "GCC 12.2.0"
  bool cuda_built = false;   ///< built with the CUDA K-nearest-neighbour backend
  bool cuda_probed = false;  ///< the device was asked (buildInfo(true))
  bool cuda_available = false;  ///< probed: knn_backend "gpu" runs as itself here (no fallback)
  std::string cuda_note;        ///< probed and not available: why
  /// \brief One line: "CPU <model>; SIMD <level> (best <best>[, GF_SIMD=..]); <compiler>;
  ///        CUDA <not built | built | yes | no (why)>".
  std::string summary;
};

/// \brief The build and run-time facts above. The SIMD level is the one in force: `GF_SIMD`
///        (read once per process) or the best one. Allocates no filter.
/// \param probe_gpu also ask the CUDA runtime for a usable device (loads the NVIDIA driver in a
///        CUDA build; without it the GPU is not touched).
BuildInfo buildInfo(bool probe_gpu = false);

}  // namespace ground_filter

#endif  // GROUND_FILTER_BUILD_INFO_H
