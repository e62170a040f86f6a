#include "normal_ground_filter_nodelet.h"

#include <pluginlib/class_list_macros.hpp>

#include "ground_filter/neighbor_search.h"

namespace ground_filter {

void NormalGroundFilterNodelet::onParamsAccepted(const NormalGroundFilterParams& params) {
  // A backend this build or machine cannot run falls back to the kd-tree: say so once per
  // selection, not per cloud.
  if (params.knn_backend != warned_backend_) {
    warned_backend_.clear();
    std::string note;
    if (!neighborSearchAvailable(params.knn_backend, &note)) {
      NODELET_WARN("knn_backend '%s' requested: %s; the kd-tree is used",
                   params.knn_backend.c_str(), note.c_str());
      warned_backend_ = params.knn_backend;
    }
  }
}

}  // namespace ground_filter

PLUGINLIB_EXPORT_CLASS(ground_filter::NormalGroundFilterNodelet, nodelet::Nodelet)
