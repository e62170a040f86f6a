// Compaction of the finite points, grid-column order (see ground_columns.cuh).
#include <cmath>

#include "cuda_util.cuh"
#include "ground_columns.cuh"
#include "normal/cpu_gpu_common.h"

namespace ground_filter {
namespace cuda_impl {

namespace {

constexpr int kThreads = kGroundThreads;

using normal::cellIndex;
using normal::columnKey;

__global__ void finiteFlagsKernel(const float* __restrict__ in, int n, unsigned int* flags) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i > n) return;
  if (i == n) {
    flags[n] = 0;
    return;
  }
  const float x = in[3 * static_cast<std::size_t>(i)], y = in[3 * static_cast<std::size_t>(i) + 1],
              z = in[3 * static_cast<std::size_t>(i) + 2];
  flags[i] = isfinite(x) && isfinite(y) && isfinite(z);
}

__global__ void compactKernel(const float* __restrict__ in, const unsigned int* __restrict__ flags,
                              const unsigned int* __restrict__ pos, int n, float* raw_xyz,
                              unsigned int* raw_src) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n || !flags[i]) return;
  const std::size_t s = 3 * static_cast<std::size_t>(i), d = 3 * static_cast<std::size_t>(pos[i]);
  raw_xyz[d] = in[s];
  raw_xyz[d + 1] = in[s + 1];
  raw_xyz[d + 2] = in[s + 2];
  raw_src[pos[i]] = static_cast<unsigned int>(i);
}

__global__ void columnKeysKernel(const float* __restrict__ xyz, int n, double min_x, double min_y,
                                 double inv_cell, unsigned long long* keys, unsigned int* vals) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const std::size_t s = 3 * static_cast<std::size_t>(i);
  const std::uint32_t cx = cellIndex(xyz[s], min_x, inv_cell);
  const std::uint32_t cy = cellIndex(xyz[s + 1], min_y, inv_cell);
  keys[i] = columnKey(cx, cy);
  vals[i] = static_cast<unsigned int>(i);
}

__global__ void gatherColumnsKernel(const float* __restrict__ raw_xyz,
                                    const unsigned int* __restrict__ raw_src,
                                    const unsigned int* __restrict__ order, int n, float* xyz,
                                    unsigned int* src) {
  const int j = blockIdx.x * blockDim.x + threadIdx.x;
  if (j >= n) return;
  const unsigned int s = order[j];
  const std::size_t a = 3 * static_cast<std::size_t>(s), b = 3 * static_cast<std::size_t>(j);
  xyz[b] = raw_xyz[a];
  xyz[b + 1] = raw_xyz[a + 1];
  xyz[b + 2] = raw_xyz[a + 2];
  src[j] = raw_src != nullptr ? raw_src[s] : s;  // null: every input point was finite
}

}  // namespace

void launchFiniteFlags(const float* in, int n, unsigned int* flags, cudaStream_t st) {
  finiteFlagsKernel<<<blocksFor(static_cast<std::size_t>(n) + 1, kThreads), kThreads, 0, st>>>(
      in, n, flags);
  GF_CUDA_CHECK_LAUNCH();
}

void launchCompact(const float* in, const unsigned int* flags, const unsigned int* pos, int n,
                   float* raw_xyz, unsigned int* raw_src, cudaStream_t st) {
  if (n == 0) return;
  compactKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(in, flags, pos, n, raw_xyz, raw_src);
  GF_CUDA_CHECK_LAUNCH();
}

void launchColumnKeys(const float* raw_xyz, int n, double min_x, double min_y, double inv_cell,
                      unsigned long long* keys, unsigned int* vals, cudaStream_t st) {
  columnKeysKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(raw_xyz, n, min_x, min_y, inv_cell,
                                                                keys, vals);
  GF_CUDA_CHECK_LAUNCH();
}

void launchGatherColumns(const float* raw_xyz, const unsigned int* raw_src,
                         const unsigned int* order, int n, float* xyz, unsigned int* src,
                         cudaStream_t st) {
  gatherColumnsKernel<<<blocksFor(n, kThreads), kThreads, 0, st>>>(raw_xyz, raw_src, order, n, xyz,
                                                                   src);
  GF_CUDA_CHECK_LAUNCH();
}

}  // namespace cuda_impl
}  // namespace ground_filter
