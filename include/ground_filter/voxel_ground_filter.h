#ifndef GROUND_FILTER_VOXEL_GROUND_FILTER_H
#define GROUND_FILTER_VOXEL_GROUND_FILTER_H

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/voxel_ground_filter_params.h"

namespace ground_filter {

/// \brief Voxel-based ground filter: flat voxels, height filter, 26-adjacency region growing,
///        plane fit(s), distance filter and a final 26-neighbourhood majority vote.
///
/// With `local_planes` (default) the single plane of the paper becomes a ground model of
/// `tile_size` cells grown outwards from the largest flat segment, each cell fitted to the
/// lowest voxels of its columns near the prediction of its neighbours (docs/voxel_method.md).
///
/// With `threads` > 1, scans of at least 150 k valid points split the key computation, sort,
/// classification and vote over that many threads; the labels are the same for any thread count.
/// Scratch buffers (and worker threads) are kept: a repeated scan of the same size allocates
/// nothing when `labels` and `stats` are reused.
class VoxelGroundFilter : public GroundFilter {
 public:
  /// \brief Validates and stores `params`.
  /// \throws std::invalid_argument when params.validate() fails.
  explicit VoxelGroundFilter(const VoxelGroundFilterParams& params = VoxelGroundFilterParams());
  ~VoxelGroundFilter() override;

  /// \brief Labels every point (NaN/Inf points are non-ground and never used). Stage timings
  ///        go to `stats->stage_ms` only when `stats` is given.
  /// \throws std::runtime_error when the cloud spans more than 2^21 voxels along an axis.
  void filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
              FilterStats* stats = nullptr) override;
  /// \brief filter(), when the bounds of the finite points (taken in the first pass anyway)
  ///        lie inside `volume`; false otherwise, and always for an airborne scan.
  bool filterInside(const CloudView& cloud, const WorkingVolume& volume,
                    std::vector<std::uint8_t>* labels, FilterStats* stats = nullptr) override;
  std::string name() const override { return "voxel"; }
  /// \brief The sensor's position: scan_type auto looks from there, and the ground model starts
  ///        from a segment that passes below it (docs/voxel_method.md). NaN: no sensor (only
  ///        with a forced scan_type; the paper mode's normalised segments).
  void setSensorOrigin(float x, float y, float z) override;
  /// \brief True when scan_type (or morph_ground) makes `cloud` an airborne scan.
  bool noSensorAtOrigin(const CloudView& cloud) override;

  /// \brief The parameters in use.
  const VoxelGroundFilterParams& params() const { return params_; }

 private:
  // filter() with the volume test of filterInside() when `volume` is given.
  bool run(const CloudView& cloud, const WorkingVolume* volume, std::vector<std::uint8_t>* labels,
           FilterStats* stats);
  struct Impl;
  VoxelGroundFilterParams params_;
  std::unique_ptr<Impl> impl_;  // scratch buffers reused between calls
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_VOXEL_GROUND_FILTER_H
