#ifndef GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOOD_PCA_H
#define GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOOD_PCA_H

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ground_filter/neighbor_search.h"

namespace ground_filter {

/// \brief Per-point PCA of a K neighbourhood, as the normal filter computes it.
struct PointPca {
  float normal[3] = {0.f, 0.f, 0.f};  ///< unit eigenvector of the smallest eigenvalue (sign free)
  float eigen[3] = {0.f, 0.f, 0.f};   ///< eigenvalues ascending, divided by their sum (0 if none)
  bool valid = false;                 ///< false when fewer than 3 neighbours or zero spread
};

/// \brief PCA of the centred covariance of every row of `lists` over packed `xyz`, in double,
///        with Eigen's closed-form 3x3 solver; `threads` 0 = all cores. Same result for any
///        thread count.
void computeNeighborhoodPca(const float* xyz, const NeighborLists& lists, int threads,
                            std::vector<PointPca>* out);

/// \brief The same PCA for the rows `rows[0..count)` only, on the calling thread: row r of the
///        `k`-wide `indices` (neighbours of point r) goes to `out[r]`; same bits as
///        computeNeighborhoodPca().
void computeRowsPca(const float* xyz, const std::int32_t* indices, int k, const std::uint32_t* rows,
                    std::size_t count, PointPca* out);

/// \brief The same PCA for `count` consecutive `k`-wide rows `rows` (row j holds the neighbours
///        of point `query[j]`; result in `out[query[j]]`), on the calling thread; same bits.
void computeOrderedRowsPca(const float* xyz, const std::int32_t* rows, int k,
                           const std::uint32_t* query, std::size_t count, PointPca* out);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_NORMAL_NEIGHBORHOOD_PCA_H
