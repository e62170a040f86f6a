#ifndef GROUND_FILTER_NEIGHBOR_SEARCH_H
#define GROUND_FILTER_NEIGHBOR_SEARCH_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace ground_filter {

struct PointPca;       // per-point PCA (private: src/core/normal/neighborhood_pca.h)
struct CandidateTest;  // ground-candidate settings (private: the same header)

/// \brief K-nearest-neighbour lists of every point of a packed xyz cloud (the point itself
///        included, at distance 0).
///
/// Row i holds `k` entries at `indices[i * k + j]`, sorted by increasing distance. When the cloud
/// has fewer than `k` points, each row has `size()` valid entries and the rest are -1.
struct NeighborLists {
  int k = 0;                          ///< entries per row
  std::size_t points = 0;             ///< number of rows
  std::vector<std::int32_t> indices;  ///< points * k neighbour indices, -1 = none
  std::vector<float> sq_dists;        ///< points * k squared distances [m^2], +inf for -1 entries
};

/// \brief A K-nearest-neighbour backend (CPU kd-tree, CUDA grid, ...), chosen at run time.
///
/// Implementations keep their scratch buffers between calls; one object per thread.
class NeighborSearch {
 public:
  virtual ~NeighborSearch() = default;
  /// \brief Finds the `k` nearest neighbours of every point among all points of `xyz`
  ///        (`n` packed float triplets, all finite).
  virtual void search(const float* xyz, std::size_t n, int k, NeighborLists* out) = 0;
  /// \brief Backend name ("kdtree", "gpu").
  virtual std::string name() const = 0;
  /// \brief Backend that ran the last search(); differs from name() after a per-scan fallback
  ///        (e.g. a CUDA error made that scan run on the kd-tree).
  virtual std::string lastBackend() const { return name(); }
  /// \brief Why the last search() did not run on name() (e.g. the CUDA error); empty otherwise.
  virtual std::string lastNote() const { return std::string(); }
  /// \brief Named parts of the last search()/searchWithPca() call and their wall times [ms], in
  ///        order (e.g. {"kdtree_build", 6.0}, {"knn", 30.0}); empty when the backend does not
  ///        time its parts (the caller then times the whole call). A reference to the backend's
  ///        own list (valid until its next call), so reading it per scan allocates nothing.
  virtual const std::vector<std::pair<std::string, double>>& lastStageMs() const {
    static const std::vector<std::pair<std::string, double>> kNone;
    return kNone;
  }

  /// \brief search() and the PCA of every list (as computeNeighborhoodPca() in
  ///        neighborhood_pca.h computes it, bit for bit) in one go, so a backend can work on each
  ///        list while it is still in cache; `out` holds the lists afterwards as after search().
  /// \return false when the backend does not do this (nothing done: call search() and
  ///        neighborhoodPca()/computeNeighborhoodPca() instead).
  virtual bool searchWithPca(const float* /*xyz*/, std::size_t /*n*/, int /*k*/,
                             NeighborLists* /*out*/, std::vector<PointPca>* /*pca*/) {
    return false;
  }

  /// \brief search() and the ground-candidate flag of every list (`candidate[i]`, `n` bytes: the
  ///        same bytes as isCandidatePca() on computeNeighborhoodPca()'s result, see
  ///        neighborhood_pca.h) in one go; `out` as after searchWithPca().
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
  ///        (neighborhood_pca.h) computes it; false when the lists are on the host.
  virtual bool neighborhoodPca(std::vector<PointPca>* /*out*/) { return false; }
  /// \brief For every point i of the last search(): `flagged[i]` = its neighbours j with
  ///        `flags[j] != 0`, `neighbors[i]` = its valid neighbours; false when the lists are on
  ///        the host.
  virtual bool countFlaggedNeighbors(const std::uint8_t* /*flags*/, std::uint16_t* /*flagged*/,
                                     std::uint16_t* /*neighbors*/) {
    return false;
  }
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_NEIGHBOR_SEARCH_H
