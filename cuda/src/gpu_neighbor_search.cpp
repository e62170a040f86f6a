#include "gpu_neighbor_search.h"

#include <algorithm>
#include <exception>
#include <stdexcept>
#include <string>
#include <utility>

#include "ground_filter/ground_filter.h"
#include "knn/neighborhood_pca.h"

namespace ground_filter {

namespace {

/// Inside a catch block: "cudaErrorX: message" of a CUDA failure, or the message of any other
/// std::exception being handled.
std::string describeCurrent() {
  try {
    throw;
  } catch (const CudaError& e) {
    return e.errorName() + ": " + e.what();
  } catch (const std::exception& e) {
    return e.what();
  }
}

}  // namespace

GpuNeighborSearch::GpuNeighborSearch(std::unique_ptr<KnnBackend> fallback,
                                     const CudaKnnOptions& options)
    : fallback_(std::move(fallback)) {
  if (!fallback_) throw std::invalid_argument("GpuNeighborSearch: null fallback");
  knn_ = std::make_unique<CudaKnn>(options);
}

GpuNeighborSearch::~GpuNeighborSearch() = default;

bool GpuNeighborSearch::keepLists(bool keep) {
  keep_on_device_ = keep;
  return keep;
}

void GpuNeighborSearch::search(const float* xyz, std::size_t n, int k, NeighborLists* out) {
  last_backend_ = "gpu";
  last_note_.clear();
  lists_on_device_ = false;
  last_xyz_ = xyz;
  last_n_ = n;
  last_k_ = k;
  last_out_ = out;
  if (k > CudaKnn::kMaxK) {
    last_note_ = "GPU backend supports k <= " + std::to_string(CudaKnn::kMaxK) +
                 ", k = " + std::to_string(k) + "; using kdtree";
  } else if (k <= 0 || n == 0) {
    out->k = std::max(k, 0);
    out->points = n;
    out->indices.assign(n * static_cast<std::size_t>(out->k), -1);
    out->sq_dists.assign(n * static_cast<std::size_t>(out->k), 0.f);
    return;
  } else {
    out->k = k;
    out->points = n;
    try {
      if (keep_on_device_) {
        out->indices.clear();
        out->sq_dists.clear();
        knn_->search(xyz, n, k, nullptr, nullptr);
        lists_on_device_ = true;
      } else {
        out->indices.resize(n * static_cast<std::size_t>(k));
        out->sq_dists.resize(n * static_cast<std::size_t>(k));
        knn_->search(xyz, n, k, out->indices.data(), out->sq_dists.data());
      }
      return;
    } catch (const std::exception&) {
      last_note_ = "GPU search failed (" + describeCurrent() + "); using kdtree";
    }
  }
  searchOnFallback(xyz, n, k, out);
}

void GpuNeighborSearch::searchOnFallback(const float* xyz, std::size_t n, int k,
                                         NeighborLists* out) {
  // This scan on the CPU; the lists are complete either way.
  fallback_->search(xyz, n, k, out);
  last_backend_ = fallback_->name();
}

void GpuNeighborSearch::recoverOnHost(const std::string& what, const std::string& error) {
  lists_on_device_ = false;
  last_note_ = "GPU " + what + " failed (" + error + "); using kdtree";
  searchOnFallback(last_xyz_, last_n_, last_k_, last_out_);
}

bool GpuNeighborSearch::neighborhoodPca(std::vector<PointPca>* out) {
  if (!lists_on_device_) return false;
  const std::size_t n = last_n_;
  try {
    pca_normals_.resize(3 * n);
    pca_eigen_.resize(3 * n);
    pca_valid_.resize(n);
    knn_->neighborhoodPca(pca_normals_.data(), pca_eigen_.data(), pca_valid_.data());
  } catch (const std::exception&) {
    recoverOnHost("PCA", describeCurrent());
    return false;
  }
  out->resize(n);
  PointPca* o = out->data();
  const float* nv = pca_normals_.data();
  const float* ev = pca_eigen_.data();
  const std::uint8_t* valid = pca_valid_.data();
#pragma omp parallel for schedule(static) if (n > 65536)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
    PointPca& r = o[i];
    for (int c = 0; c < 3; ++c) {
      r.normal[c] = nv[3 * i + c];
      r.eigen[c] = ev[3 * i + c];
    }
    r.valid = valid[i] != 0;
  }
  return true;
}

bool GpuNeighborSearch::countFlaggedNeighbors(const std::uint8_t* flags, std::uint16_t* flagged,
                                              std::uint16_t* neighbors) {
  if (!lists_on_device_) return false;
  try {
    knn_->countFlaggedNeighbors(flags, flagged, neighbors);
  } catch (const std::exception&) {
    recoverOnHost("neighbour count", describeCurrent());
    return false;
  }
  return true;
}

// ------------------------------------------------ the core's entry points (knn/knn_backend.h)

bool gpuKnnAvailable(std::string* note) {
  std::string why;
  if (CudaKnn::deviceAvailable(&why)) return true;
  if (note) *note = "GPU backend unavailable: " + why + "; using kdtree";
  return false;
}

std::unique_ptr<KnnBackend> makeGpuKnnBackend(std::unique_ptr<KnnBackend> fallback,
                                              std::string* note) {
  std::string why;
  if (CudaKnn::deviceAvailable(&why)) {
    try {
      return std::make_unique<GpuNeighborSearch>(std::move(fallback));
    } catch (const std::exception& e) {
      why = e.what();
    }
  }
  if (note) *note = "GPU backend unavailable: " + why + "; using kdtree";
  return nullptr;
}

}  // namespace ground_filter
