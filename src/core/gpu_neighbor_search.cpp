#include "ground_filter/gpu_neighbor_search.h"

#include <exception>
#include <string>

#include "ground_filter/kdtree_neighbor_search.h"

namespace ground_filter {

GpuNeighborSearch::GpuNeighborSearch(int threads, const CudaKnnOptions& options)
    : knn_(std::make_unique<CudaKnn>(options)), threads_(threads) {}

GpuNeighborSearch::~GpuNeighborSearch() = default;

void GpuNeighborSearch::search(const float* xyz, std::size_t n, int k, NeighborLists* out) {
  last_backend_ = "gpu";
  last_note_.clear();
  if (k > CudaKnn::kMaxK) {
    last_note_ = "GPU backend supports k <= " + std::to_string(CudaKnn::kMaxK) + ", k = " +
                 std::to_string(k) + "; using kdtree";
  } else if (k <= 0 || n == 0) {
    out->k = k > 0 ? k : 0;
    out->points = n;
    out->indices.clear();
    out->sq_dists.clear();
    out->indices.resize(n * static_cast<std::size_t>(out->k), -1);
    out->sq_dists.resize(n * static_cast<std::size_t>(out->k));
    return;
  } else {
    out->k = k;
    out->points = n;
    out->indices.resize(n * static_cast<std::size_t>(k));
    out->sq_dists.resize(n * static_cast<std::size_t>(k));
    try {
      knn_->search(xyz, n, k, out->indices.data(), out->sq_dists.data());
      return;
    } catch (const CudaError& e) {
      last_note_ = "GPU search failed (" + e.errorName() + ": " + e.what() + "); using kdtree";
    } catch (const std::exception& e) {
      last_note_ = std::string("GPU search failed (") + e.what() + "); using kdtree";
    }
  }
  // This scan on the CPU; the lists are complete either way.
  if (!fallback_) fallback_ = std::make_unique<KdTreeNeighborSearch>(threads_);
  fallback_->search(xyz, n, k, out);
  last_backend_ = fallback_->name();
}

}  // namespace ground_filter
