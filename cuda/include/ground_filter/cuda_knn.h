#ifndef GROUND_FILTER_CUDA_KNN_H
#define GROUND_FILTER_CUDA_KNN_H

// Host-clean interface of the CUDA K-nearest-neighbour library (ground_filter_cuda): no CUDA
// types, so plain C++ compilers include it. Only linkable when the package is built with CUDA.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

namespace ground_filter {

struct CudaKnnTuningAccess;

/// \brief A failed CUDA call or a device-side limit (e.g. the memory cap); errorName() is the
///        CUDA error's name ("cudaErrorMemoryAllocation", ...).
class CudaError : public std::runtime_error {
 public:
  /// \brief `error_name` is the CUDA error's name, `what` the full message.
  CudaError(const std::string& error_name, const std::string& what)
      : std::runtime_error(what), error_name_(error_name) {}
  /// \brief Name of the CUDA error, e.g. "cudaErrorNoDevice".
  const std::string& errorName() const { return error_name_; }

 private:
  std::string error_name_;
};

/// \brief Options of a CudaKnn instance.
struct CudaKnnOptions {
  int device = 0;                ///< CUDA device ordinal [index] (0)
  std::size_t memory_limit = 0;  ///< device bytes this instance may hold, 0 = 90 % of free [B] (0)
};

/// \brief Wall times of the last CudaKnn calls (host clock, streams synchronised) [ms].
struct CudaKnnTimings {
  double upload_ms = 0.0;  ///< host -> device copy of the points
  double grid_ms = 0.0;    ///< bounds, Morton sort, cell tables
  double query_ms = 0.0;   ///< the query kernel, with the overlapped download of the lists
  double total_ms = 0.0;   ///< the whole search()
  double pca_ms = 0.0;     ///< the last neighborhoodPca(), downloads included
  double count_ms = 0.0;   ///< the last countFlaggedNeighbors(), copies included
  int levels = 0;          ///< grid levels built (finest has 2^finest_bits cells per axis)
  int finest_bits = 0;     ///< log2 of cells per axis of the finest level
};

/// \brief Exact K-nearest-neighbour search on a CUDA GPU over a whole cloud at once.
///
/// Points are sorted along a Morton curve; each power-of-two grid level over the bounding cube is a
/// hashed cell list (memory O(points), independent of the cloud's extent). One warp per query
/// bounds its K-th distance by the K points before and after it on the curve, picks a level from
/// that bound and its own cell's count, then visits shells of cells, skipping cells farther than
/// the bound or the current K-th distance, until no unvisited cell can hold a closer point. Rows
/// are ordered by (squared distance, index), so the lists equal a brute-force search's with ties
/// broken by lower index. Device and pinned buffers persist and grow only when a cloud is larger
/// than before; kernels run on one stream of this instance, downloads on a second one so they
/// overlap the queries. Not thread-safe: one per thread.
class CudaKnn {
  friend class CudaNormalPipeline;    // runs the search on points already on the device
  friend struct CudaKnnTuningAccess;  // experiment knobs of the tests and the benchmark (private)

 public:
  /// \brief Largest supported K.
  static constexpr int kMaxK = 64;

  /// \brief True when device `device` exists and runs this library's kernels; otherwise `*why`
  ///        (if not null) says why, naming the CUDA error.
  static bool deviceAvailable(std::string* why, int device = 0);

  /// \brief Selects the device and creates the stream.
  /// \throws CudaError when no usable device is there.
  explicit CudaKnn(const CudaKnnOptions& options = CudaKnnOptions());
  ~CudaKnn();
  CudaKnn(const CudaKnn&) = delete;
  CudaKnn& operator=(const CudaKnn&) = delete;

  /// \brief Finds the `k` nearest neighbours (itself included) of each of the `n` packed xyz
  ///        points among all of them.
  ///
  /// Writes `n * k` entries to `indices` and, when not null, `sq_dists` (row i at i * k, increasing
  /// (distance, index); -1 / +inf padding when n < k). With `indices` null nothing is downloaded:
  /// the lists stay on the device for neighborhoodPca() and countFlaggedNeighbors(). Points must
  /// be finite.
  /// \throws std::invalid_argument for k outside [1, kMaxK], n >= 2^31 or a NaN/Inf point.
  /// \throws CudaError for any CUDA failure or when the memory limit is too small.
  void search(const float* xyz, std::size_t n, int k, std::int32_t* indices, float* sq_dists);

  /// \brief PCA of every neighbourhood of the last search(), on the device, as the core's
  ///        computeNeighborhoodPca() does it (double precision, Eigen's closed-form solver):
  ///        `normals` (3 per point, unit eigenvector of the smallest eigenvalue), `eigenvalues`
  ///        (3 per point, ascending, divided by their sum), `valid` (1 per point; 0 with zeros
  ///        when fewer than 3 neighbours or no spread). Arrays hold n entries per component.
  /// \throws std::logic_error without a successful search(); CudaError on a CUDA failure.
  void neighborhoodPca(float* normals, float* eigenvalues, std::uint8_t* valid);

  /// \brief For every point of the last search(): `flagged[i]` = its neighbours j with
  ///        `flags[j] != 0`, `neighbors[i]` = its valid neighbours (n entries each).
  /// \throws std::logic_error without a successful search(); CudaError on a CUDA failure.
  void countFlaggedNeighbors(const std::uint8_t* flags, std::uint16_t* flagged,
                             std::uint16_t* neighbors);

  /// \brief Points of the lists kept on the device (0 when none).
  std::size_t listPoints() const;
  /// \brief Timings of the last calls.
  const CudaKnnTimings& lastTimings() const;
  /// \brief Device name, e.g. "NVIDIA H200".
  std::string deviceName() const;
  /// \brief Device bytes held now (persistent buffers).
  std::size_t deviceBytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_KNN_H
