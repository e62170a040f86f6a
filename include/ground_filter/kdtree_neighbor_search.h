#ifndef GROUND_FILTER_KDTREE_NEIGHBOR_SEARCH_H
#define GROUND_FILTER_KDTREE_NEIGHBOR_SEARCH_H

#include <cstddef>
#include <memory>
#include <string>

#include "ground_filter/neighbor_search.h"

namespace ground_filter {

/// \brief CPU K-nearest-neighbour search: a nanoflann kd-tree over the cloud, queries in
///        parallel (OpenMP), exact results.
///
/// Ties at equal distance are ordered by lower point index first inside a row; which of several
/// points at exactly the K-th distance is kept is unspecified (but the same for any thread
/// count). The tree and scratch memory are kept between calls.
class KdTreeNeighborSearch : public NeighborSearch {
 public:
  /// \brief `threads` query threads (0 = all cores); `leaf_size` points per kd-tree leaf.
  explicit KdTreeNeighborSearch(int threads = 0, int leaf_size = 16);
  ~KdTreeNeighborSearch() override;

  void search(const float* xyz, std::size_t n, int k, NeighborLists* out) override;
  std::string name() const override { return "kdtree"; }

  /// \brief Wall time of the tree build in the last search() [ms].
  double lastBuildMs() const { return build_ms_; }
  /// \brief Wall time of the queries in the last search() [ms].
  double lastQueryMs() const { return query_ms_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int threads_;
  int leaf_size_;
  double build_ms_ = 0.0;
  double query_ms_ = 0.0;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_KDTREE_NEIGHBOR_SEARCH_H
