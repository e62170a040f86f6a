#ifndef GROUND_FILTER_WORKING_VOLUME_H
#define GROUND_FILTER_WORKING_VOLUME_H

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"
#include "ground_filter/working_volume_params.h"

namespace ground_filter {

/// \brief A GroundFilter that runs another one on the points inside a WorkingVolume only.
///
/// Points outside the volume (one far echo, a corrupt 1e30 m value) are labelled kNonGround one
/// by one and counted in FilterStats::out_of_range_points; points within min_range or the body
/// box likewise, counted in FilterStats::near_points; the inner filter sees the rest. The
/// inner filter may check the volume on its way (GroundFilter::filterInside(); the voxel filter
/// tests the bounds it takes anyway), else a first pass checks every point; when all finite
/// points are inside (the usual case) the view goes to the inner filter as it is, without a
/// copy. Otherwise the finite in-range points are
/// packed, in input order, into a scratch xyz buffer, filtered, and their labels scattered
/// back, so every other point gets the label it would get without the far points. A cloud with
/// no sensor at its origin (scan_type airborne or registered, or more than half of its finite
/// points beyond the hard box whatever scan_type says) whose points lie beyond the hard box, as
/// a survey tile or map in projected coordinates, has the box moved onto its middle
/// (recentre()) and is filtered relative to it.
class WorkingVolumeFilter : public GroundFilter {
 public:
  /// \brief Wraps `inner` (not null).
  /// \throws std::invalid_argument when `volume` is invalid or `inner` is null.
  WorkingVolumeFilter(std::unique_ptr<GroundFilter> inner, const WorkingVolume& volume);

  void filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
              FilterStats* stats = nullptr) override;
  /// \brief The inner filter's name.
  std::string name() const override { return inner_->name(); }

  /// \brief Moves the volume's centre (e.g. to the sensor origin in a gravity frame).
  void setOrigin(float x, float y, float z);
  /// \brief setOrigin(): the sensor origin is the volume's centre.
  void setSensorOrigin(float x, float y, float z) override { setOrigin(x, y, z); }
  /// \brief Sets the sensor pose in the view's frame: origin and row-major rotation (sensor to
  ///        view), e.g. the transform into a gravity frame; the inner filter's sensor origin
  ///        too (its sensor rules: scan_type, planes above the sensor).
  void setPose(const float origin[3], const float rotation[9]);
  /// \brief The volume in use.
  const WorkingVolume& volume() const { return volume_; }
  /// \brief The wrapped filter.
  GroundFilter& inner() { return *inner_; }

 private:
  /// Points sampled per axis to find the middle of a far cloud (recentre()).
  static constexpr std::size_t kRecentreSamples = 8192;

  // A cloud with no sensor at its origin whose points lie beyond the hard box (a map or survey
  // tile in projected coordinates): moves the box onto the middle of the cloud (whole metres,
  // into `shift`; min_range and body_box off) when it then holds more of the cloud than
  // `*out_of_range` leaves out, which then counts the finite points outside the moved box.
  // False, shift 0: the volume and the count as they were.
  bool recentre(const CloudView& cloud, std::size_t* out_of_range, WorkingVolume* volume,
                float shift[3]);

  // The inner filter on the packed points (xyz_) into inner_labels_; with `shift` (the points
  // moved by it: recentre()) its sensor origin moves alike for the call.
  void filterPacked(const float* shift, FilterStats* inner_stats);

  std::unique_ptr<GroundFilter> inner_;
  WorkingVolume volume_;
  std::vector<float> xyz_;         // packed in-range points
  std::vector<std::size_t> kept_;  // their input indices
  std::vector<std::uint8_t> inner_labels_;
  std::vector<float> axis_;  // recentre()'s sample of one axis
  bool ask_inner_ = true;    // try GroundFilter::filterInside() first (see filter())
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_WORKING_VOLUME_H
