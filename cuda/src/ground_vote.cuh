// Private: PCA candidates and the naive-Bayes vote over the KNN rows on the device
// (CPU: isFlat and the naive-Bayes vote of the normal method).
#ifndef GROUND_FILTER_CUDA_SRC_GROUND_VOTE_CUH
#define GROUND_FILTER_CUDA_SRC_GROUND_VOTE_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "ground_common.cuh"

namespace ground_filter {
namespace cuda_impl {

/// CPU: SampleStage::gather's choice: flags[i] = 1 where ordered point i is sampled (n points,
/// `keys` their sorted column keys; flags[n] = 0): every stride-th point, or in a column of more
/// than stride * cap points every columnSampleStep()-th from its first.
void launchSampleFlags(const unsigned long long* keys, int n, int stride, int cap,
                       unsigned int* flags, cudaStream_t st);
/// sidx[pos[i]] = i for each sampled point (pos: exclusive scan of flags, n + 1 entries), and
/// sidx[pos[n]] = n.
void launchSampleIndex(const unsigned int* flags, const unsigned int* pos, int n,
                       unsigned int* sidx, cudaStream_t st);
/// CPU: SampleStage::gather: sampled[j] = xyz[sidx[j]] (x y z packed), j < m.
void launchSampleGather(const float* xyz, const unsigned int* sidx, int m, float* sampled,
                        cudaStream_t st);
/// CPU: SampleStage::spread: a sampled point's vote, another point's the OR of the sampled
/// points before and after it (m sampled points, n points; flags and pos as above).
void launchSpreadVotes(const std::uint8_t* sampled_voted, const unsigned int* flags,
                       const unsigned int* pos, int m, int n, std::uint8_t* voted, cudaStream_t st);
/// PCA of every KNN row, flatness and normal test: cand[original index] (0/1); cand_count += them.
void launchPcaCandidates(const float* xyz, const float4* pts, const std::int32_t* rows, int n,
                         const GroundParamsDev& p, std::uint8_t* cand, unsigned int* cand_count,
                         cudaStream_t st);
/// Naive-Bayes vote over each KNN row (or a copy of cand without bayes_vote).
void launchVote(const float4* pts, const std::int32_t* rows, int n, const GroundParamsDev& p,
                const std::uint8_t* cand, const unsigned int* cand_count, std::uint8_t* voted,
                cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GROUND_VOTE_CUH
