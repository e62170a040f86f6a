#ifndef GROUND_FILTER_CUDA_TEST_BRUTE_FORCE_KNN_H
#define GROUND_FILTER_CUDA_TEST_BRUTE_FORCE_KNN_H

// Reference K-nearest neighbours for the GPU tests: every pair, same float arithmetic as the GPU
// ((dx*dx + dy*dy) + dz*dz, no FMA), rows ordered by (squared distance, index).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace gf_test {

/// \brief Exact row of query `q`: k entries, -1 / +inf padding when n < k.
void bruteForceRow(const float* xyz, std::size_t n, std::size_t q, int k, std::int32_t* idx,
                   float* d2);

/// \brief "" when row `q` of (idx, d2) equals the brute-force row exactly, else a description.
std::string compareRow(const float* xyz, std::size_t n, std::size_t q, int k,
                       const std::int32_t* idx, const float* d2);

/// \brief Compares the rows `queries` (all rows when empty) in parallel; returns the number of
///        mismatching rows and the first mismatch's description in `first`.
std::size_t compareRows(const float* xyz, std::size_t n, int k, const std::int32_t* idx,
                        const float* d2, const std::vector<std::size_t>& queries,
                        std::string* first);

/// \brief Reads a KITTI .bin (x y z intensity float32 records) into packed xyz; empty if missing.
std::vector<float> readKittiBin(const std::string& path);

}  // namespace gf_test

#endif  // GROUND_FILTER_CUDA_TEST_BRUTE_FORCE_KNN_H
