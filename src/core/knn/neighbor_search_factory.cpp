// The neighbour backends by name: the public makeNeighborSearch() and the normal filter's
// makeKnnBackend() (knn_backend.h) make the same objects.

#include <stdexcept>

#include "ground_filter/neighbor_search.h"
#include "knn/kdtree_neighbor_search.h"
#include "knn/knn_backend.h"

#ifdef GROUND_FILTER_HAVE_CUDA
#include "ground_filter/cuda_knn.h"
#include "knn/gpu_neighbor_search.h"
#endif

namespace ground_filter {

std::vector<std::string> neighborSearchBackends() { return {"kdtree", "gpu"}; }

bool neighborSearchAvailable(const std::string& backend, std::string* why) {
  if (why) why->clear();
  if (backend == "kdtree") return true;
#ifdef GROUND_FILTER_HAVE_CUDA
  if (backend == "gpu") {
    std::string error;
    if (CudaKnn::deviceAvailable(&error)) return true;
    if (why) *why = "GPU backend unavailable: " + error + "; using kdtree";
    return false;
  }
#else
  if (backend == "gpu") {
    if (why) *why = "GPU backend not available: built without CUDA";
    return false;
  }
#endif
  if (why) *why = "unknown knn_backend '" + backend + "'";
  return false;
}

std::unique_ptr<KnnBackend> makeKnnBackend(const std::string& backend, int threads,
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

std::unique_ptr<NeighborSearch> makeNeighborSearch(const std::string& backend, int threads,
                                                   std::string* note) {
  return makeKnnBackend(backend, threads, note);
}

}  // namespace ground_filter
