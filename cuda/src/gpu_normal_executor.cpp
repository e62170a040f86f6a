#include "gpu_normal_executor.h"

#include <exception>
#include <string>
#include <utility>

#include "normal/cpu_gpu_common.h"

namespace ground_filter {

GpuNormalExecutor::GpuNormalExecutor(const CudaNormalParams& settings,
                                     const CudaKnnOptions& options)
    : settings_(settings), pipeline_(std::make_unique<CudaNormalPipeline>(options)) {}

GpuNormalExecutor::~GpuNormalExecutor() = default;

bool GpuNormalExecutor::run(const CloudView& cloud, int sample_stride, const double* sensor,
                            std::vector<std::uint8_t>* labels, FilterStats* stats) {
  try {
    labels->resize(cloud.size());
    CudaNormalParams settings = settings_;
    settings.sample_stride = sample_stride;
    settings.sensor_check = sensor ? 1 : 0;
    for (int a = 0; a < 3; ++a) settings.sensor[a] = sensor ? sensor[a] : 0.0;
    pipeline_->run(cloud, settings, labels->data());
  } catch (const CudaError& e) {
    last_note_ = "GPU filter failed (" + e.errorName() + ": " + e.what() + "); using kdtree";
    return false;
  } catch (const std::exception& e) {
    last_note_ = "GPU filter failed (" + std::string(e.what()) + "); using kdtree";
    return false;
  }
  last_note_.clear();
  const CudaNormalTimings& t = pipeline_->lastTimings();
  stats->invalid_points = cloud.size() - t.valid_points;
  stats->ground_points = t.ground_points;
  stats->backend = name();
  if (t.sample_stride != sample_stride) {
    normal::appendSparseLinesNote(sample_stride, t.sample_stride, &stats->note);
  }
  // Appended: the filter's own stages before the executor ("lines") stay.
  const std::pair<const char*, double> stages[] = {
      {"pack", t.pack_ms},   {"upload", t.upload_ms},    {"sort", t.sort_ms},
      {"knn", t.knn_ms},     {"pca", t.pca_ms},          {"vote", t.vote_ms},
      {"plane", t.plane_ms}, {"download", t.download_ms}};
  for (const auto& s : stages) stats->stage_ms.emplace_back(s.first, s.second);
  return true;
}

bool GpuNormalExecutor::lastColumnOrder(std::vector<std::uint32_t>* source) {
  try {
    pipeline_->lastColumnOrder(source);
  } catch (const std::exception&) {
    return false;  // the filter sorts the points itself
  }
  return true;
}

// The core's entry point (normal/filter_executor.h).
std::unique_ptr<NormalFilterExecutor> makeGpuNormalExecutor(const NormalGroundFilterParams& params,
                                                            double min_abs_nz) {
  std::string why;
  if (params.k > CudaKnn::kMaxK || !CudaKnn::deviceAvailable(&why)) return nullptr;
  try {
    return std::make_unique<GpuNormalExecutor>(CudaNormalParams(params, min_abs_nz));
  } catch (const std::exception&) {
    return nullptr;  // the neighbour backend's factory reports the same failure
  }
}

}  // namespace ground_filter
