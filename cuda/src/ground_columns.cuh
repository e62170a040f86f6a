// Private: compaction of the finite points and their grid-column order (the start of
// NormalGroundFilter::filter() on the device).
#ifndef GROUND_FILTER_CUDA_SRC_GROUND_COLUMNS_CUH
#define GROUND_FILTER_CUDA_SRC_GROUND_COLUMNS_CUH

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "ground_common.cuh"

namespace ground_filter {
namespace cuda_impl {

/// flags[i] = point i of the packed input is finite (i < n); flags[n] = 0.
void launchFiniteFlags(const float* in, int n, unsigned int* flags, cudaStream_t st);
/// Compacts the finite points (pos = exclusive scan of the flags): raw_xyz, raw_src (input
/// index). Their count and x/y bounds come from the host's packing, so no sync waits for them.
void launchCompact(const float* in, const unsigned int* flags, const unsigned int* pos, int n,
                   float* raw_xyz, unsigned int* raw_src, cudaStream_t st);
/// Morton key of the x/y grid column of every compacted point (CPU: cellIndex + spreadBits).
void launchColumnKeys(const float* raw_xyz, int n, double min_x, double min_y, double inv_cell,
                      unsigned long long* keys, unsigned int* vals, cudaStream_t st);
/// xyz[j] = raw_xyz[order[j]], src[j] = raw_src[order[j]] (order[j] where raw_src is null).
void launchGatherColumns(const float* raw_xyz, const unsigned int* raw_src,
                         const unsigned int* order, int n, float* xyz, unsigned int* src,
                         cudaStream_t st);

}  // namespace cuda_impl
}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GROUND_COLUMNS_CUH
