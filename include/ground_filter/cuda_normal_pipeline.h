#ifndef GROUND_FILTER_CUDA_NORMAL_PIPELINE_H
#define GROUND_FILTER_CUDA_NORMAL_PIPELINE_H

// Host-clean interface of the whole normal-vector filter on a CUDA GPU (ground_filter_cuda): no
// CUDA types. Only linkable when the package is built with CUDA.

#include <cstddef>
#include <cstdint>
#include <memory>

#include "ground_filter/cloud_view.h"
#include "ground_filter/cuda_knn.h"

namespace ground_filter {

/// \brief Parameters of CudaNormalPipeline::run(); the meaning of NormalGroundFilterParams's
///        fields of the same names (use_segments is not supported: the whole cloud is one set).
struct CudaNormalParams {
  int k = 50;                    ///< neighbours per sampled point, itself included (1..kMaxK)
  int sample_stride = 1;         ///< normals and vote on every n-th ordered point (1..16)
  double cell_size = 0.10;       ///< x/y grid cell ordering points into columns [m]
  double min_abs_nz = 0.0;       ///< |n_z| of a candidate's and of a plane's normal, at least [1]
  double min_planarity = 0.0;    ///< flat: planarity dominant and >= this [1]
  bool bayes_vote = true;        ///< naive-Bayes vote over each K neighbourhood
  double plane_distance = 0.15;  ///< max point-to-plane distance of a ground point [m]
  bool std_filter = false;       ///< also require the mean +- std band of distances
  double std_multiplier = 1.0;   ///< width of that band in standard deviations [1]
  int ransac_iterations = 100;   ///< RANSAC hypotheses per plane, at most
  int ransac_seed = 0;           ///< RANSAC generator seed, 0 = the built-in one
  bool plane_all_points = true;  ///< plane test labels every point, not only voted ones
  bool local_planes = true;      ///< one plane per tile instead of one for the cloud
  double tile_size = 4.0;        ///< tile edge for local planes [m]
  double floor_share = 0.15;     ///< sparse tile: lowest-level share moving the cloud plane, 0 off
  double floor_max_shift = 0.5;  ///< sparse tile: largest move of the cloud-wide plane [m]
  int local_ground_min = 0;      ///< local ground: ground neighbours needed, 0 = off
  double local_ground_below = 0.10;  ///< local ground: under their plane at most [m]
  double local_ground_above = 0.05;  ///< local ground: over their plane at most [m]
};

/// \brief Device times of the stages of the last run() (CUDA events) and its counts.
struct CudaNormalTimings {
  double pack_ms = 0.0;           ///< host: copy of the view's xyz into pinned memory (wall)
  double upload_ms = 0.0;         ///< host -> device copy of xyz
  double sort_ms = 0.0;           ///< NaN/Inf compaction, grid-column (Morton) order
  double knn_ms = 0.0;            ///< K nearest neighbours (grid build and queries)
  double pca_ms = 0.0;            ///< PCA, flatness and normal test (candidates)
  double vote_ms = 0.0;           ///< naive-Bayes vote
  double plane_ms = 0.0;          ///< tiles, RANSAC planes, distance test
  double download_ms = 0.0;       ///< device -> host copy of the labels
  double total_ms = 0.0;          ///< the whole run() (wall, host xyz in to host labels out)
  std::size_t valid_points = 0;   ///< finite points
  std::size_t ground_points = 0;  ///< points labelled ground
  std::size_t tiles = 0;          ///< plane tiles
};

/// \brief The whole normal-vector filter (NormalGroundFilter::filter) on a CUDA GPU.
///
/// One upload of xyz, compaction of the finite points, grid-column order, KNN (CudaKnn's grid),
/// PCA, naive-Bayes vote, tile RANSAC (SplitMix64 seeded per tile, as on the CPU) and the
/// distance test on the device, one download of the labels. Buffers persist and only grow; all
/// work runs on the CudaKnn's stream. Every step mirrors the CPU code's arithmetic in double
/// without FMA contraction, so the labels equal the CPU backend's (see docs/gpu.md for the
/// measured agreement). Not thread-safe: one per thread.
class CudaNormalPipeline {
 public:
  /// \brief Selects the device (options as CudaKnn's; memory_limit covers all buffers).
  /// \throws CudaError when no usable device is there.
  explicit CudaNormalPipeline(const CudaKnnOptions& options = CudaKnnOptions());
  ~CudaNormalPipeline();
  CudaNormalPipeline(const CudaNormalPipeline&) = delete;
  CudaNormalPipeline& operator=(const CudaNormalPipeline&) = delete;

  /// \brief Labels every point of `cloud` (kGround = 1 / kNonGround = 0; NaN/Inf points 0) into
  ///        `labels` (cloud.size() entries).
  /// \throws std::invalid_argument for k outside [1, CudaKnn::kMaxK] or >= 2^31 points.
  /// \throws CudaError for any CUDA failure or when the memory limit is too small.
  void run(const CloudView& cloud, const CudaNormalParams& params, std::uint8_t* labels);

  /// \brief Stage times and counts of the last run().
  const CudaNormalTimings& lastTimings() const;
  /// \brief The KNN search it uses (its own calls work as a standalone CudaKnn).
  CudaKnn& knn();
  /// \brief Device bytes held now by the pipeline and its KNN (persistent buffers).
  std::size_t deviceBytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_NORMAL_PIPELINE_H
