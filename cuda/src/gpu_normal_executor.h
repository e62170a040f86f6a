#ifndef GROUND_FILTER_CUDA_SRC_GPU_NORMAL_EXECUTOR_H
#define GROUND_FILTER_CUDA_SRC_GPU_NORMAL_EXECUTOR_H

// The core's whole-filter executor (normal/filter_executor.h) on the CUDA pipeline: part of the
// CUDA library, which includes the core's headers (never the other way). The filter gets it
// through makeGpuNormalExecutor().

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cuda_knn.h"
#include "ground_filter/cuda_normal_pipeline.h"
#include "normal/filter_executor.h"

namespace ground_filter {

/// \brief The whole normal filter on a CUDA GPU (CudaNormalPipeline) with the settings of one
///        parameter set, built once. Any CUDA error in a run declines that one scan (the filter
///        runs its CPU stages; lastNote() names the error); the next scan tries the GPU again.
class GpuNormalExecutor : public NormalFilterExecutor {
 public:
  /// \brief For the settings of one parameter set (built once: CudaNormalParams(params,
  ///        normal::minAbsNormalZ(params)); normal::gpuSupports(params) must hold).
  /// \throws CudaError when no usable CUDA device is there.
  explicit GpuNormalExecutor(const CudaNormalParams& settings,
                             const CudaKnnOptions& options = CudaKnnOptions());
  ~GpuNormalExecutor() override;

  std::string name() const override { return "gpu"; }
  bool run(const CloudView& cloud, int sample_stride, const double* sensor,
           std::vector<std::uint8_t>* labels, FilterStats* stats) override;
  std::string lastNote() const override { return last_note_; }
  bool lastColumnOrder(std::vector<std::uint32_t>* source) override;

  /// \brief The pipeline (timings of the last run).
  const CudaNormalPipeline& pipeline() const { return *pipeline_; }

 private:
  CudaNormalParams settings_;
  std::unique_ptr<CudaNormalPipeline> pipeline_;
  std::string last_note_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GPU_NORMAL_EXECUTOR_H
