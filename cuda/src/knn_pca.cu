// PCA and vote-count kernels over the KNN lists kept on the device.
#include "cuda_util.cuh"
#include "knn_pca.cuh"

namespace ground_filter {
namespace cuda_impl {

namespace {

/// PCA of sorted row s, written at the point's original index.
__global__ void pcaKernel(const float* __restrict__ xyz, const float4* __restrict__ pts,
                          const std::int32_t* __restrict__ rows, int n, int k,
                          float* __restrict__ normals, float* __restrict__ eigen,
                          std::uint8_t* __restrict__ valid) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= n) return;
  const float4 qp = pts[s];
  const std::size_t orig = static_cast<std::size_t>(__float_as_int(qp.w));
  float nv[3], ev[3];
  const bool ok =
      neighborhoodPcaOf(xyz, rows + static_cast<std::size_t>(s) * k, k, qp.x, qp.y, qp.z, nv, ev);
  for (int r = 0; r < 3; ++r) {
    normals[3 * orig + r] = nv[r];
    eigen[3 * orig + r] = ev[r];
  }
  valid[orig] = ok;
}

/// For sorted row s: neighbours whose flag is set, and valid neighbours; at the original index.
__global__ void countKernel(const float4* __restrict__ pts, const std::int32_t* __restrict__ rows,
                            int n, int k, const std::uint8_t* __restrict__ flags,
                            std::uint16_t* __restrict__ flagged,
                            std::uint16_t* __restrict__ neighbors) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= n) return;
  const std::int32_t* row = rows + static_cast<std::size_t>(s) * k;
  int m = 0, u = 0;
  for (; m < k; ++m) {
    const int j = row[m];
    if (j < 0) break;
    u += flags[j] != 0;
  }
  const int orig = __float_as_int(pts[s].w);
  flagged[orig] = static_cast<std::uint16_t>(u);
  neighbors[orig] = static_cast<std::uint16_t>(m);
}

}  // namespace

void launchPca(const float* xyz, const float4* pts, const std::int32_t* rows, int n, int k,
               float* normals, float* eigen, std::uint8_t* valid, cudaStream_t st) {
  pcaKernel<<<blocksFor(n, 128), 128, 0, st>>>(xyz, pts, rows, n, k, normals, eigen, valid);
  GF_CUDA_CHECK_LAUNCH();
}

void launchCountFlagged(const float4* pts, const std::int32_t* rows, int n, int k,
                        const std::uint8_t* flags, std::uint16_t* flagged, std::uint16_t* neighbors,
                        cudaStream_t st) {
  countKernel<<<blocksFor(n, 256), 256, 0, st>>>(pts, rows, n, k, flags, flagged, neighbors);
  GF_CUDA_CHECK_LAUNCH();
}

}  // namespace cuda_impl
}  // namespace ground_filter
