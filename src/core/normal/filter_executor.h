#ifndef GROUND_FILTER_SRC_CORE_NORMAL_FILTER_EXECUTOR_H
#define GROUND_FILTER_SRC_CORE_NORMAL_FILTER_EXECUTOR_H

// An executor of the whole normal-vector filter beside the CPU pipeline (the stages of
// NormalGroundFilter::filter()): the filter chooses one when its parameters ask for it
// (knn_backend gpu, settings the GPU honours) and runs its own stages when it declines a scan.
// The neighbour backends (knn/knn_backend.h) only search.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/normal_ground_filter_params.h"

namespace ground_filter {

/// \brief The whole normal filter on another device, for one parameter set (given when it is
///        made).
class NormalFilterExecutor {
 public:
  virtual ~NormalFilterExecutor() = default;
  /// \brief Its name in FilterStats::backend ("gpu").
  virtual std::string name() const = 0;
  /// \brief Labels `cloud` as NormalGroundFilter::filter()'s stages would with `sample_stride`
  ///        (the parameter's, or wider for a sparse sensor's scan lines): fills `labels`
  ///        (cloud.size() entries) and, in `stats`, invalid_points, ground_points and backend,
  ///        and appends its stages to stage_ms (after the filter's own, e.g. "lines").
  ///        `sensor`: x, y, z of the scan's sensor, or null (PlaneStage::run()).
  /// \return false, touching neither, when it cannot run this scan (lastNote() says why, e.g. a
  ///         device fault); the filter then runs its stages. The next scan tries again.
  virtual bool run(const CloudView& cloud, int sample_stride, const double* sensor,
                   std::vector<std::uint8_t>* labels, FilterStats* stats) = 0;
  /// \brief Why the last run() declined; empty after one that ran.
  virtual std::string lastNote() const = 0;
  /// \brief After a run() that labelled the scan: the input index of each of its finite points
  ///        in grid-column order (OrderStage's order, columnKey() of cell_size cells) into
  ///        `source`. false where the executor keeps no such order (the filter then sorts the
  ///        points itself).
  virtual bool lastColumnOrder(std::vector<std::uint32_t>* source) {
    (void)source;
    return false;
  }
};

/// \brief The CUDA executor (CudaNormalPipeline) for `params` and their |n_z| bound
///        `min_abs_nz` (normal::minAbsNormalZ(params)), or null when there is no usable device,
///        k is above what it searches (CudaKnn::kMaxK) or the package is built without CUDA.
///        Call only where normal::gpuSupports(params). Defined by the CUDA library
///        (cuda/src/gpu_normal_executor.cpp), or by src/core/no_cuda.cpp without CUDA.
std::unique_ptr<NormalFilterExecutor> makeGpuNormalExecutor(const NormalGroundFilterParams& params,
                                                            double min_abs_nz);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_FILTER_EXECUTOR_H
