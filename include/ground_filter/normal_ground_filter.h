#ifndef GROUND_FILTER_NORMAL_GROUND_FILTER_H
#define GROUND_FILTER_NORMAL_GROUND_FILTER_H

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/normal_ground_filter_params.h"

namespace ground_filter {

class KnnBackend;            // the core's neighbour backends (private: src/core/knn/knn_backend.h)
class NormalFilterExecutor;  // the whole filter elsewhere (private:
                             // src/core/normal/filter_executor.h)

/// \brief Normal-vector ground filter: K nearest neighbours, PCA normal and flatness per point,
///        ground candidates by normal angle, naive-Bayes neighbourhood vote, RANSAC plane(s) and
///        a distance filter.
class NormalGroundFilter : public GroundFilter {
 public:
  /// \brief Validates and stores `params`; creates the neighbour backend and, for knn_backend
  ///        `gpu` with settings the GPU honours, the GPU executor of the whole filter (a `gpu`
  ///        request without CUDA falls back to the kd-tree, reported in FilterStats::note).
  /// \throws std::invalid_argument when params.validate() fails.
  explicit NormalGroundFilter(const NormalGroundFilterParams& params = NormalGroundFilterParams());
  /// \brief As above with the neighbour backend of the CPU stages given instead of made from
  ///        params.knn_backend, and no executor: one of the core's backends (tests and
  ///        benchmarks inside the package, which see the private knn_backend.h).
  /// \throws std::invalid_argument when params.validate() fails or `search` is null.
  NormalGroundFilter(const NormalGroundFilterParams& params, std::unique_ptr<KnnBackend> search);
  /// \brief As above with the executor of the whole filter given too (null: none), e.g. a
  ///        GpuNormalExecutor with its own CudaKnnOptions (tests, private filter_executor.h).
  NormalGroundFilter(const NormalGroundFilterParams& params, std::unique_ptr<KnnBackend> search,
                     std::unique_ptr<NormalFilterExecutor> executor);
  ~NormalGroundFilter() override;

  void filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
              FilterStats* stats = nullptr) override;
  std::string name() const override { return "normal"; }
  /// \brief The origin scan_type auto looks from.
  void setSensorOrigin(float x, float y, float z) override;
  /// \brief True when scan_type (or morph_ground) makes `cloud` an airborne scan.
  bool noSensorAtOrigin(const CloudView& cloud) override;

  /// \brief The parameters in use.
  const NormalGroundFilterParams& params() const { return params_; }
  /// \brief Name of the neighbour backend actually used ("kdtree", "gpu").
  std::string backend() const;
  /// \brief Why the requested backend is not the one used; empty when it is.
  const std::string& backendNote() const { return backend_note_; }

 private:
  struct Impl;
  NormalGroundFilterParams params_;
  std::string backend_note_;
  std::unique_ptr<Impl> impl_;  // neighbour backend and scratch buffers reused between calls
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_NORMAL_GROUND_FILTER_H
