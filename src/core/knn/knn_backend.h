#ifndef GROUND_FILTER_SRC_CORE_KNN_KNN_BACKEND_H
#define GROUND_FILTER_SRC_CORE_KNN_KNN_BACKEND_H

// The neighbour backends' private interface: what the normal filter uses beyond the public
// NeighborSearch (include/ground_filter/neighbor_search.h). It only searches: the work on lists
// a backend keeps is a NeighborListStore it hands out (knn/neighbor_list_store.h), and the whole
// filter on another device is an executor beside the CPU stages (normal/filter_executor.h).
// Every backend of the core derives from KnnBackend; a part a backend does not have keeps its
// default (false = not done, nothing touched), and the filter then takes the plain path.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/neighbor_search.h"
#include "knn/neighbor_list_store.h"
#include "knn/neighborhood_pca.h"

namespace ground_filter {

/// \brief A NeighborSearch with the optional parts the normal filter uses.
class KnnBackend : public NeighborSearch {
 public:
  /// \brief search() and the PCA of every list (as computeNeighborhoodPca() computes it, bit for
  ///        bit) in one go, so a backend can work on each list while it is still in cache; `out`
  ///        holds the lists afterwards as after search().
  /// \return false when the backend does not do this (nothing done: call search() and
  ///        neighborhoodPca()/computeNeighborhoodPca() instead).
  virtual bool searchWithPca(const float* /*xyz*/, std::size_t /*n*/, int /*k*/,
                             NeighborLists* /*out*/, std::vector<PointPca>* /*pca*/) {
    return false;
  }

  /// \brief search() and the ground-candidate flag of every list (`candidate[i]`, `n` bytes: the
  ///        same bytes as isCandidatePca() on computeNeighborhoodPca()'s result) in one go; `out`
  ///        as after searchWithPca().
  /// \return false when the backend does not do this (nothing done).
  virtual bool searchWithCandidates(const float* /*xyz*/, std::size_t /*n*/, int /*k*/,
                                    const CandidateTest& /*test*/, NeighborLists* /*out*/,
                                    std::uint8_t* /*candidate*/) {
    return false;
  }

  /// \brief Where the backend keeps its lists (and works on them there), or null when it always
  ///        returns them in search()'s `out`.
  virtual NeighborListStore* listStore() { return nullptr; }
};

/// \brief makeNeighborSearch() with the private interface: the backend the normal filter holds.
std::unique_ptr<KnnBackend> makeKnnBackend(const std::string& backend, int threads,
                                           std::string* note);

// The CUDA neighbour search: defined by the CUDA library (cuda/src/gpu_neighbor_search.cpp)
// where the package is built with CUDA, otherwise by src/core/no_cuda.cpp. The core reaches the
// GPU only through these and makeGpuNormalExecutor() (normal/filter_executor.h).

/// \brief True when the GPU search runs here; otherwise false and `*note` (if not null) is the
///        filter's note saying why ("GPU backend unavailable: <CUDA error>; using kdtree", or
///        "GPU backend not available: built without CUDA").
bool gpuKnnAvailable(std::string* note);
/// \brief The CUDA search, scans it cannot do (a CUDA error, k above its limit) on `fallback`;
///        null, with `*note` as gpuKnnAvailable()'s, when there is no usable device.
std::unique_ptr<KnnBackend> makeGpuKnnBackend(std::unique_ptr<KnnBackend> fallback,
                                              std::string* note);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_KNN_KNN_BACKEND_H
