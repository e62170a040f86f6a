#ifndef GROUND_FILTER_SRC_NODELETS_NORMAL_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_NORMAL_GROUND_FILTER_NODELET_H

#include <string>

#include "ground_filter/NormalGroundFilterConfig.h"
#include "ground_filter/normal_ground_filter.h"
#include "reconfigurable_filter_nodelet.h"

namespace ground_filter {

/// \brief Nodelet `ground_filter/NormalGroundFilter`: the normal-vector method on
///        GroundFilterNodelet, parameters from cfg/NormalGroundFilter.cfg through
///        dynamic_reconfigure; `knn_backend` switches the neighbour search at run time.
class NormalGroundFilterNodelet
    : public ReconfigurableFilterNodelet<NormalGroundFilterConfig, NormalGroundFilterParams,
                                         NormalGroundFilter> {
 protected:
  void onParamsAccepted(const NormalGroundFilterParams& params) override;

 private:
  std::string warned_backend_;  // backend whose fallback was last warned about (one warning)
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_NORMAL_GROUND_FILTER_NODELET_H
