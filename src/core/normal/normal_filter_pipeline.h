#ifndef GROUND_FILTER_SRC_CORE_NORMAL_NORMAL_FILTER_PIPELINE_H
#define GROUND_FILTER_SRC_CORE_NORMAL_NORMAL_FILTER_PIPELINE_H

#include <cstdint>
#include <vector>

#include "ground_filter/cloud_view.h"

namespace ground_filter {

struct FilterStats;               // ground_filter.h
struct NormalGroundFilterParams;  // normal_ground_filter_params.h

/// \brief Optional second interface of a NeighborSearch backend that can run the whole
///        normal-vector filter where its lists live (the GPU backend).
///
/// NormalGroundFilter::filter() offers every scan to it first; when runNormalFilter() returns
/// false the filter runs its usual steps on the same backend for that scan.
class NormalFilterPipeline {
 public:
  virtual ~NormalFilterPipeline() = default;
  /// \brief Labels `cloud` as NormalGroundFilter::filter() would with `params`: fills `labels`
  ///        (cloud.size() entries) and, in `stats`, invalid_points, ground_points, backend and
  ///        stage_ms. Returns false, touching neither, when it cannot run this scan (then the
  ///        backend's lastBackend()/lastNote() say why, e.g. a device fault).
  virtual bool runNormalFilter(const CloudView& cloud, const NormalGroundFilterParams& params,
                               std::vector<std::uint8_t>* labels, FilterStats* stats) = 0;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_NORMAL_FILTER_PIPELINE_H
