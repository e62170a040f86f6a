#ifndef GROUND_FILTER_CUDA_NORMAL_PIPELINE_H
#define GROUND_FILTER_CUDA_NORMAL_PIPELINE_H

// Host-clean interface of the whole normal-vector filter on a CUDA GPU (ground_filter_cuda): no
// CUDA types. Only linkable when the package is built with CUDA.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/cuda_knn.h"
#include "ground_filter/params/normal_filter_settings.h"

namespace ground_filter {

/// \brief Settings of CudaNormalPipeline::run(), host and device alike (the kernels take it by
///        value): the normal method's plain parameters (NormalFilterSettings, generated from
///        include/ground_filter/params/normal_params.def, so a NormalGroundFilterParams is one;
///        use_segments and veg_filter are not supported: the whole cloud is one set) and the
///        |n_z| bound derived from its normal-angle window. Built once per parameter set.
struct CudaNormalParams : NormalFilterSettings {
  CudaNormalParams() = default;
  /// \brief The settings `s` and their |n_z| bound (the core's normal::minAbsNormalZ()).
  CudaNormalParams(const NormalFilterSettings& s, double min_abs_nz_of_s)
      : NormalFilterSettings(s), min_abs_nz(min_abs_nz_of_s) {}
  double min_abs_nz = 0.0;  ///< |n_z| of a candidate's and of a plane's normal, at least [1]
  /// 1: the scan has its sensor at `sensor` and no ground plane may pass above it (the core's
  /// normal::planeAboveSensor(), where normal::sensorAboveGround() holds); 0: no sensor.
  int sensor_check = 0;
  double sensor[3] = {0.0, 0.0, 0.0};  ///< the sensor's x, y, z in the cloud's frame [m]
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
  /// The stride the labels come from: sample_stride, or wider where too few sampled points
  /// were ground candidates (min_candidate_share; the CPU filter's rule).
  int sample_stride = 0;
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
  /// \throws std::invalid_argument for k outside [1, CudaKnn::kMaxK], sample_stride below 1
  ///         (the other ranges are NormalGroundFilterParams::validate()'s) or >= 2^31 points.
  /// \throws CudaError for any CUDA failure or when the memory limit is too small.
  void run(const CloudView& cloud, const CudaNormalParams& params, std::uint8_t* labels);

  /// \brief Stage times and counts of the last run().
  const CudaNormalTimings& lastTimings() const;
  /// \brief The input index of each finite point of the last run(), in its grid-column order
  ///        (lastTimings().valid_points entries), into `source`: one download, on request (the
  ///        filter's step after the pipeline reads the points in that order).
  /// \throws CudaError for any CUDA failure.
  void lastColumnOrder(std::vector<std::uint32_t>* source);
  /// \brief The KNN search it uses (its own calls work as a standalone CudaKnn); its
  ///        deviceBytes() counts the pipeline's buffers too (one memory limit for all).
  CudaKnn& knn();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_CUDA_NORMAL_PIPELINE_H
