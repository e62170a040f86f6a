#ifndef GROUND_FILTER_SRC_CORE_KNN_KNN_BACKEND_H
#define GROUND_FILTER_SRC_CORE_KNN_KNN_BACKEND_H

// The neighbour backends' private interface: what the normal filter uses beyond the public
// NeighborSearch (include/ground_filter/neighbor_search.h): searches and work on their lists.
// The whole filter on another device is an executor beside the CPU stages instead
// (normal/filter_executor.h). Every backend of the core derives from
// KnnBackend; a part a backend does not have keeps its default (false = not done, nothing
// touched), and the filter then takes the plain path.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/neighbor_search.h"
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

  // Optional work on the lists where they were computed (GPU memory), so they need not come back
  // to the host. A backend without it keeps the defaults (lists always on the host).

  /// \brief Asks the backend to keep the lists of later search() calls on its device when it can;
  ///        search() then fills `k` and `points` but may leave `indices`/`sq_dists` empty, and
  ///        neighborhoodPca()/countFlaggedNeighbors() work on the kept lists. Whenever one of
  ///        those returns false, the last search()'s lists are in its `out` on the host instead.
  /// \return whether the backend keeps lists on a device.
  virtual bool keepListsOnDevice(bool /*keep*/) { return false; }
  /// \brief PCA of every neighbourhood of the last search(), as computeNeighborhoodPca()
  ///        computes it; false when the lists are on the host.
  virtual bool neighborhoodPca(std::vector<PointPca>* /*out*/) { return false; }
  /// \brief For every point i of the last search(): `flagged[i]` = its neighbours j with
  ///        `flags[j] != 0`, `neighbors[i]` = its valid neighbours; false when the lists are on
  ///        the host.
  virtual bool countFlaggedNeighbors(const std::uint8_t* /*flags*/, std::uint16_t* /*flagged*/,
                                     std::uint16_t* /*neighbors*/) {
    return false;
  }

  /// \brief The last search()'s lists where the backend kept them on the host in its own row
  ///        order: row r (`k` entries, all valid, at `rows + r * k`) is the list of point
  ///        `points[r]`; false when they are in search()'s `out` (or on a device).
  virtual bool keptRows(const std::int32_t** /*rows*/, const std::uint32_t** /*points*/) const {
    return false;
  }
};

/// \brief makeNeighborSearch() with the private interface: the backend the normal filter holds.
std::unique_ptr<KnnBackend> makeKnnBackend(const std::string& backend, int threads,
                                           std::string* note);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_KNN_KNN_BACKEND_H
