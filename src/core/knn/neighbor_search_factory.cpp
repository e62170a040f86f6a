// The neighbour backends by name: the public makeNeighborSearch() and the normal filter's
// makeKnnBackend() (knn_backend.h) make the same objects. The GPU search comes from the CUDA
// library's makeGpuKnnBackend() (or src/core/no_cuda.cpp's, which says it is not built).

#include <stdexcept>

#include "ground_filter/neighbor_search.h"
#include "knn/kdtree_neighbor_search.h"
#include "knn/knn_backend.h"

namespace ground_filter {

std::vector<std::string> neighborSearchBackends() { return {"kdtree", "gpu"}; }

bool neighborSearchAvailable(const std::string& backend, std::string* why) {
  if (why) why->clear();
  if (backend == "kdtree") return true;
  if (backend == "gpu") return gpuKnnAvailable(why);
  if (why) *why = "unknown knn_backend '" + backend + "'";
  return false;
}

std::unique_ptr<KnnBackend> makeKnnBackend(const std::string& backend, int threads,
                                           std::string* note) {
  if (note) note->clear();
  if (backend == "kdtree") return std::make_unique<KdTreeNeighborSearch>(threads);
  if (backend == "gpu") {
    // The kd-tree serves the scans the GPU cannot do, or every scan where there is no GPU.
    auto gpu = makeGpuKnnBackend(std::make_unique<KdTreeNeighborSearch>(threads), note);
    if (gpu) return gpu;
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
