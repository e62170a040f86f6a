#include "normal_ground_filter_nodelet.h"

#include <pluginlib/class_list_macros.hpp>
#include <sstream>

#include "ground_filter/neighbor_search_factory.h"

namespace ground_filter {

NormalGroundFilterParams normalParamsFromConfig(const NormalGroundFilterConfig& config) {
  NormalGroundFilterParams p;
  p.cell_size = config.cell_size;
  p.k = config.k;
  p.min_normal_angle = config.min_normal_angle;
  p.max_normal_angle = config.max_normal_angle;
  p.min_planarity = config.min_planarity;
  p.bayes_vote = config.bayes_vote;
  p.plane_distance = config.plane_distance;
  p.std_filter = config.std_filter;
  p.std_multiplier = config.std_multiplier;
  p.ransac_iterations = config.ransac_iterations;
  p.plane_all_points = config.plane_all_points;
  p.local_planes = config.local_planes;
  p.tile_size = config.tile_size;
  p.use_segments = config.use_segments;
  p.segment_points = config.segment_points;
  p.knn_backend = config.knn_backend;
  p.threads = config.threads;
  return p;
}

std::string describeNormalParams(const NormalGroundFilterParams& p) {
  std::ostringstream os;
  os << std::boolalpha << "knn_backend=" << p.knn_backend << " k=" << p.k
     << " cell_size=" << p.cell_size << " min_normal_angle=" << p.min_normal_angle
     << " max_normal_angle=" << p.max_normal_angle << " min_planarity=" << p.min_planarity
     << " bayes_vote=" << p.bayes_vote << " plane_distance=" << p.plane_distance
     << " std_filter=" << p.std_filter << " std_multiplier=" << p.std_multiplier
     << " ransac_iterations=" << p.ransac_iterations << " plane_all_points=" << p.plane_all_points
     << " local_planes=" << p.local_planes << " tile_size=" << p.tile_size
     << " use_segments=" << p.use_segments << " segment_points=" << p.segment_points
     << " threads=" << p.threads;
  return os.str();
}

void NormalGroundFilterNodelet::onParamsAccepted(const NormalGroundFilterParams& params) {
  // A backend this build or machine cannot run falls back to the kd-tree: say so once per
  // selection, not per cloud.
  if (params.knn_backend != warned_backend_) {
    warned_backend_.clear();
    if (!neighborSearchAvailable(params.knn_backend)) {
      std::string note;
      makeNeighborSearch(params.knn_backend, 1, &note);
      NODELET_WARN("knn_backend '%s' requested: %s; the kd-tree is used",
                   params.knn_backend.c_str(), note.c_str());
      warned_backend_ = params.knn_backend;
    }
  }
}

}  // namespace ground_filter

PLUGINLIB_EXPORT_CLASS(ground_filter::NormalGroundFilterNodelet, nodelet::Nodelet)
