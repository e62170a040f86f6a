#ifndef GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOODS_H
#define GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOODS_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/neighbor_search.h"
#include "knn/knn_backend.h"
#include "knn/neighborhood_pca.h"
#include "normal/stage_times.h"

namespace ground_filter {
namespace normal {

/// \brief Stages 2-3 ("kdtree_build", "knn", "pca"): K nearest neighbours of every point of a
///        segment, the PCA of each neighbourhood, and the ground candidates (flat, normal within
///        the angle window). Holds only scratch memory (the PCA), reused between scans.
class NeighborhoodStage {
 public:
  /// \brief Runs on the `len` packed points `xyz` with `search`: the lists go to `lists` (whose
  ///        indices may stay empty when the backend keeps them on its device, see
  ///        NeighborListStore::keepLists()), candidate[i] = 1 for the candidates (`len` entries
  ///        written). Stage times are added to `times`. `lattice_var` (null: none) is added to
  ///        each covariance where the backend decides the candidates with the lists
  ///        (the kd-tree; CandidateTest::lattice_var); the GPU's per-stage PCA has none.
  /// \return the number of candidates.
  std::size_t run(KnnBackend* search, const float* xyz, std::size_t len, int k, int threads,
                  double min_planarity, double min_abs_nz, const double* lattice_var,
                  NeighborLists* lists, std::uint8_t* candidate, StageTimes* times);

 private:
  std::vector<PointPca> pca_;
};

}  // namespace normal
}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOODS_H
