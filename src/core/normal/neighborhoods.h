#ifndef GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOODS_H
#define GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOODS_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/neighbor_search.h"
#include "normal/neighborhood_pca.h"
#include "stage_times.h"

namespace ground_filter {
namespace normal {

/// \brief Dimensionality features of Demantke et al. from the normalised eigenvalues: flat when
///        planarity is the largest of linearity, planarity, scattering and >= `min_planarity`.
bool isFlat(const PointPca& r, double min_planarity);

/// \brief Stages 2-3 ("kdtree_build", "knn", "pca"): K nearest neighbours of every point of a
///        segment, the PCA of each neighbourhood, and the ground candidates (flat, normal within
///        the angle window).
class NeighborhoodStage {
 public:
  /// \brief Runs on the `len` packed points `xyz` with `search`; candidate[i] = 1 for the
  ///        candidates (`len` entries written). Stage times are added to `times`.
  /// \return the number of candidates.
  std::size_t run(NeighborSearch* search, const float* xyz, std::size_t len, int k, int threads,
                  double min_planarity, double min_abs_nz, std::uint8_t* candidate,
                  StageTimes* times);
  /// \brief The neighbour lists of the last run() (may be empty when a GPU backend keeps them).
  const NeighborLists& lists() const { return lists_; }

 private:
  NeighborLists lists_;
  std::vector<PointPca> pca_;
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOODS_H
