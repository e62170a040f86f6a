#ifndef GROUND_FILTER_CUDA_SRC_GPU_NEIGHBOR_SEARCH_H
#define GROUND_FILTER_CUDA_SRC_GPU_NEIGHBOR_SEARCH_H

// The core's neighbour interfaces (knn/knn_backend.h, knn/neighbor_list_store.h) on the CUDA
// search: part of the CUDA library, which includes the core's headers (never the other way).
// The core makes it through makeGpuKnnBackend() (makeNeighborSearch("gpu", ...),
// makeKnnBackend("gpu", ...)), with the kd-tree as its fallback.

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cuda_knn.h"
#include "ground_filter/neighbor_search.h"
#include "knn/knn_backend.h"
#include "knn/neighbor_list_store.h"

namespace ground_filter {

/// \brief NeighborSearch on a CUDA GPU (CudaKnn); a scan the GPU cannot do runs on the fallback
///        (the kd-tree).
///        (The whole normal filter on the GPU is an executor of its own: GpuNormalExecutor.)
///
/// Any CUDA error during a search (or k above CudaKnn::kMaxK) makes that one scan run on the
/// fallback instead; lastBackend() and lastNote() then say so and name the error. The next scan
/// tries the GPU again.
class GpuNeighborSearch : public KnnBackend, public NeighborListStore {
 public:
  /// \brief `fallback` (not null) searches the scans the GPU cannot do.
  /// \throws CudaError when no usable CUDA device is there.
  explicit GpuNeighborSearch(std::unique_ptr<KnnBackend> fallback,
                             const CudaKnnOptions& options = CudaKnnOptions());
  ~GpuNeighborSearch() override;

  void search(const float* xyz, std::size_t n, int k, NeighborLists* out) override;
  std::string name() const override { return "gpu"; }
  std::string lastBackend() const override { return last_backend_; }
  std::string lastNote() const override { return last_note_; }

  /// \brief Itself: it keeps the lists of search() in GPU memory.
  NeighborListStore* listStore() override { return this; }
  /// \brief With `keep`, search() leaves the lists in GPU memory (`out` gets k and points only)
  ///        for the two calls below. `xyz` and `out` of the last search() must stay alive until
  ///        those are done: on a CUDA error there, the scan is redone on the fallback into `out`.
  bool keepLists(bool keep) override;
  bool neighborhoodPca(std::vector<PointPca>* out) override;
  bool countFlaggedNeighbors(const std::uint8_t* flags, std::uint16_t* flagged,
                             std::uint16_t* neighbors) override;

  /// \brief The CUDA search (timings of the last GPU search, device name).
  const CudaKnn& cudaKnn() const { return *knn_; }

 private:
  /// Runs the last search again on the fallback into its `out` after a CUDA error in `what`.
  void recoverOnHost(const std::string& what, const std::string& error);
  /// search() on the fallback: this scan on the CPU.
  void searchOnFallback(const float* xyz, std::size_t n, int k, NeighborLists* out);

  std::unique_ptr<CudaKnn> knn_;
  std::unique_ptr<KnnBackend> fallback_;
  std::string last_backend_ = "gpu";
  std::string last_note_;
  bool keep_on_device_ = false;
  bool lists_on_device_ = false;  // the last search's lists are (only) in GPU memory
  const float* last_xyz_ = nullptr;
  std::size_t last_n_ = 0;
  int last_k_ = 0;
  NeighborLists* last_out_ = nullptr;
  std::vector<float> pca_normals_, pca_eigen_;  // scratch of neighborhoodPca()
  std::vector<std::uint8_t> pca_valid_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_SRC_GPU_NEIGHBOR_SEARCH_H
