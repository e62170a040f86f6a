#ifndef GROUND_FILTER_NEIGHBORS_NEIGHBOR_SEARCH_FACTORY_H
#define GROUND_FILTER_NEIGHBORS_NEIGHBOR_SEARCH_FACTORY_H

#include <memory>
#include <string>
#include <vector>

#include "ground_filter/neighbor_search.h"

namespace ground_filter {

/// \brief Names accepted by makeNeighborSearch ("kdtree", "gpu"), whether or not built with CUDA.
std::vector<std::string> neighborSearchBackends();

/// \brief True when this build can run `backend` as itself (no fallback); "kdtree" always can.
bool neighborSearchAvailable(const std::string& backend);

/// \brief Creates the K-nearest-neighbour backend `backend` using `threads` CPU threads
///        (0 = all cores) for whatever runs on the CPU.
///
/// A backend this build cannot provide falls back to the kd-tree; the reason is then written to
/// `*note` (e.g. "GPU backend not available: built without CUDA"), otherwise `*note` is cleared.
/// The returned object's name() is the backend actually used. The CUDA build adds its backend
/// here (under GROUND_FILTER_HAVE_CUDA).
/// \throws std::invalid_argument for a name not in neighborSearchBackends().
std::unique_ptr<NeighborSearch> makeNeighborSearch(const std::string& backend, int threads,
                                                   std::string* note);

}  // namespace ground_filter

#endif  // GROUND_FILTER_NEIGHBORS_NEIGHBOR_SEARCH_FACTORY_H
