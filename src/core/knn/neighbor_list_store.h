#ifndef GROUND_FILTER_SRC_CORE_KNN_NEIGHBOR_LIST_STORE_H
#define GROUND_FILTER_SRC_CORE_KNN_NEIGHBOR_LIST_STORE_H

// Work on the lists of a backend's last search where the backend keeps them (GPU memory, or the
// kd-tree's own row order), so they need not come back to the host in input order. Not a
// search: a backend that keeps lists hands this out (KnnBackend::listStore()); one that does not
// returns null, and its lists are always in search()'s `out`.

#include <cstdint>
#include <vector>

#include "knn/neighborhood_pca.h"

namespace ground_filter {

/// \brief The lists a neighbour backend keeps, and the work the normal filter's stages do on
///        them. A part a store does not have keeps its default (false = not done, nothing
///        touched): the stage then works on search()'s `out` on the host.
class NeighborListStore {
 public:
  virtual ~NeighborListStore() = default;

  /// \brief Asks the backend to keep the lists of later searches where it can (see the
  ///        backend's own description: which searches, which place); those searches then fill
  ///        `k` and `points` of their `out` but may leave `indices`/`sq_dists` empty. Whenever
  ///        one of the calls below returns false, the last search's lists are in its `out`.
  /// \return whether the backend keeps lists.
  virtual bool keepLists(bool keep) = 0;
  /// \brief PCA of every neighbourhood of the last search, as computeNeighborhoodPca()
  ///        computes it; false when the lists are on the host.
  virtual bool neighborhoodPca(std::vector<PointPca>* /*out*/) { return false; }
  /// \brief For every point i of the last search: `flagged[i]` = its neighbours j with
  ///        `flags[j] != 0`, `neighbors[i]` = its valid neighbours; false when the lists are in
  ///        the search's `out`.
  virtual bool countFlaggedNeighbors(const std::uint8_t* /*flags*/, std::uint16_t* /*flagged*/,
                                     std::uint16_t* /*neighbors*/) {
    return false;
  }
  /// \brief The last search's lists where the backend kept them on the host in its own row
  ///        order: row r (`k` entries, all valid, at `rows + r * k`) is the list of point
  ///        `points[r]`; false when they are in the search's `out` (or on a device).
  virtual bool keptRows(const std::int32_t** /*rows*/, const std::uint32_t** /*points*/) const {
    return false;
  }
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_KNN_NEIGHBOR_LIST_STORE_H
