#include "ground_filter/neighbors/neighbor_search_factory.h"

#include <stdexcept>

#include "neighbors/kdtree_neighbor_search.h"

#ifdef GROUND_FILTER_HAVE_CUDA
#include "ground_filter/cuda_knn.h"
#include "neighbors/gpu_neighbor_search.h"
#endif

namespace ground_filter {

std::vector<std::string> neighborSearchBackends() { return {"kdtree", "gpu"}; }

bool neighborSearchAvailable(const std::string& backend) {
  if (backend == "kdtree") return true;
#ifdef GROUND_FILTER_HAVE_CUDA
  if (backend == "gpu") return CudaKnn::deviceAvailable(nullptr);
#endif
  return false;
}

std::unique_ptr<NeighborSearch> makeNeighborSearch(const std::string& backend, int threads,
                                                   std::string* note) {
  if (note) note->clear();
  if (backend == "kdtree") return std::make_unique<KdTreeNeighborSearch>(threads);
  if (backend == "gpu") {
#ifdef GROUND_FILTER_HAVE_CUDA
    std::string why;
    if (CudaKnn::deviceAvailable(&why)) {
      try {
        return std::make_unique<GpuNeighborSearch>(threads);
      } catch (const std::exception& e) {
        why = e.what();
      }
    }
    if (note) *note = "GPU backend unavailable: " + why + "; using kdtree";
#else
    if (note) *note = "GPU backend not available: built without CUDA";
#endif
    return std::make_unique<KdTreeNeighborSearch>(threads);
  }
  std::string known;
  for (const auto& b : neighborSearchBackends()) known += (known.empty() ? "" : ", ") + b;
  throw std::invalid_argument("unknown knn_backend '" + backend + "' (known: " + known + ")");
}

}  // namespace ground_filter
