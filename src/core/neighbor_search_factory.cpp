#include "ground_filter/neighbor_search_factory.h"

#include <stdexcept>

#include "ground_filter/kdtree_neighbor_search.h"

namespace ground_filter {

std::vector<std::string> neighborSearchBackends() { return {"kdtree", "gpu"}; }

bool neighborSearchAvailable(const std::string& backend) {
  if (backend == "kdtree") return true;
  // The CUDA build answers for "gpu" here (GROUND_FILTER_HAVE_CUDA).
  return false;
}

std::unique_ptr<NeighborSearch> makeNeighborSearch(const std::string& backend, int threads,
                                                   std::string* note) {
  if (note) note->clear();
  if (backend == "kdtree") return std::make_unique<KdTreeNeighborSearch>(threads);
  if (backend == "gpu") {
    // The CUDA build creates its backend here (GROUND_FILTER_HAVE_CUDA).
    if (note) *note = "GPU backend not available: built without CUDA";
    return std::make_unique<KdTreeNeighborSearch>(threads);
  }
  std::string known;
  for (const auto& b : neighborSearchBackends()) known += (known.empty() ? "" : ", ") + b;
  throw std::invalid_argument("unknown knn_backend '" + backend + "' (known: " + known + ")");
}

}  // namespace ground_filter
