#ifndef GROUND_FILTER_SRC_CORE_KNN_NEIGHBORHOOD_PCA_H
#define GROUND_FILTER_SRC_CORE_KNN_NEIGHBORHOOD_PCA_H

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

/// \brief isFlat() of the normal filter: planarity dominant (Demantke et al.) and at least
///        `min_planarity`.
bool isFlatPca(const PointPca& r, double min_planarity);

/// \brief The ground-candidate decision on a PCA result: valid, flat and |normal z| >= `min_abs_nz`
///        (the reference the candidate-only functions below reproduce).
bool isCandidatePca(const PointPca& r, double min_planarity, double min_abs_nz);

/// \brief Settings of the candidate-only PCA.
struct CandidateTest {
  double min_planarity = 0.0;  ///< isFlatPca()'s bound [1] (0)
  double min_abs_nz = 0.0;     ///< least |normal z| of a candidate [1] (0)
  double eigen_tol = 1e-6;     ///< margin of the fast decision, in units of the trace [1] (1e-6)
  bool exact_only = false;     ///< always take the Eigen path (reference) [bool] (false)
  /// Added to the covariance's x, y, z variances: coordinates stored on a lattice hide the
  /// neighbourhood's spread inside a step (step^2 / 12, normal/lattice.h) [m^2] (0).
  double lattice_var[3] = {0.0, 0.0, 0.0};
};

/// \brief How the candidate-only PCA decided its points.
struct CandidateCounts {
  std::size_t invalid = 0;  ///< fewer than 3 neighbours or no spread: not candidates
  std::size_t early = 0;    ///< rejected from the covariance's zz entry alone
  std::size_t fast = 0;     ///< decided by the characteristic polynomial with certain margins
  std::size_t exact = 0;    ///< decided by Eigen's solver (the fallback)
};

/// \brief candidate[i] = isCandidatePca(PCA of row i, ...) for every row of `lists`, the same
///        bytes as computeNeighborhoodPca() followed by isCandidatePca(), but the eigen solver
///        runs only where the cheap decision's margins are not certain. `counts` may be null.
void computeNeighborhoodCandidates(const float* xyz, const NeighborLists& lists, int threads,
                                   const CandidateTest& t, std::uint8_t* candidate,
                                   CandidateCounts* counts);

/// \brief computeRowsPca() writing the candidate byte `candidate[r]` instead of the PCA; counts
///        are added to `counts`.
void computeRowsCandidates(const float* xyz, const std::int32_t* indices, int k,
                           const std::uint32_t* rows, std::size_t count, const CandidateTest& t,
                           std::uint8_t* candidate, CandidateCounts* counts);

/// \brief computeOrderedRowsPca() writing the candidate byte `candidate[query[j]]` instead of the
///        PCA; counts are added to `counts`.
void computeOrderedRowsCandidates(const float* xyz, const std::int32_t* rows, int k,
                                  const std::uint32_t* query, std::size_t count,
                                  const CandidateTest& t, std::uint8_t* candidate,
                                  CandidateCounts* counts);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_KNN_NEIGHBORHOOD_PCA_H
