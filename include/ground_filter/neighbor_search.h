#ifndef GROUND_FILTER_NEIGHBOR_SEARCH_H
#define GROUND_FILTER_NEIGHBOR_SEARCH_H

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace ground_filter {

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

/// \brief A K-nearest-neighbour backend (CPU kd-tree, CUDA grid, ...), chosen at run time
///        (makeNeighborSearch()).
///
/// Implementations keep their scratch buffers between calls; one object per thread. The core's
/// own backends have more (fused PCA, lists kept on the GPU, the whole normal filter on the GPU)
/// behind a private interface the normal filter uses; this is what a caller needs.
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
  /// \brief Named parts of the last search() call and their wall times [ms], in order (e.g.
  ///        {"kdtree_build", 6.0}, {"knn", 30.0}); empty when the backend does not time its parts
  ///        (the caller then times the whole call). A reference to the backend's own list (valid
  ///        until its next call), so reading it per scan allocates nothing.
  virtual const std::vector<std::pair<std::string, double>>& lastStageMs() const {
    static const std::vector<std::pair<std::string, double>> kNone;
    return kNone;
  }
};

/// \brief Names accepted by makeNeighborSearch() ("kdtree", "gpu"), whether or not built with
///        CUDA.
std::vector<std::string> neighborSearchBackends();

/// \brief True when this build and machine can run `backend` as itself (no fallback); "kdtree"
///        always can. Otherwise `*why` (when given) gets the note makeNeighborSearch() would
///        report (e.g. "GPU backend not available: built without CUDA"). Cheap: builds nothing.
bool neighborSearchAvailable(const std::string& backend, std::string* why = nullptr);

/// \brief Creates the K-nearest-neighbour backend `backend` using `threads` CPU threads
///        (0 = all cores) for whatever runs on the CPU.
///
/// A backend this build cannot provide falls back to the kd-tree; the reason is then written to
/// `*note` (e.g. "GPU backend not available: built without CUDA"), otherwise `*note` is cleared.
/// The returned object's name() is the backend actually used.
/// \throws std::invalid_argument for a name not in neighborSearchBackends().
std::unique_ptr<NeighborSearch> makeNeighborSearch(const std::string& backend, int threads,
                                                   std::string* note);

}  // namespace ground_filter

#endif  // GROUND_FILTER_NEIGHBOR_SEARCH_H
