#ifndef GROUND_FILTER_SRC_CORE_NORMAL_NORMAL_SETTINGS_H
#define GROUND_FILTER_SRC_CORE_NORMAL_NORMAL_SETTINGS_H

// Settings derived from NormalGroundFilterParams (normal_settings.cpp). The GPU pipeline takes
// the params' NormalFilterSettings base as they are (CudaNormalParams), so a new plain parameter
// reaches it without a copy.

#include "ground_filter/normal_ground_filter_params.h"

namespace ground_filter {
namespace normal {

/// \brief Least |normal z| of a ground candidate and of a plane: the cosine of the tilt the
///        normal-angle window allows, min(90 - min_normal_angle, max_normal_angle - 90) degrees.
double minAbsNormalZ(const NormalGroundFilterParams& p);

/// \brief True when the GPU pipeline (CudaNormalPipeline) runs the filter with `p` as the CPU
///        steps do: not with segments or the bush-base rule (veg_filter); k above CudaKnn::kMaxK
///        the GPU executor declines itself (makeGpuNormalExecutor()).
bool gpuSupports(const NormalGroundFilterParams& p);

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_NORMAL_SETTINGS_H
