#ifndef GROUND_FILTER_GROUND_FILTER_H
#define GROUND_FILTER_GROUND_FILTER_H

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief Per-point label values written by every filter.
enum Label : std::uint8_t {
  kNonGround = 0,  ///< not ground; also every NaN/Inf point
  kGround = 1,     ///< ground
};

/// \brief What one call of GroundFilter::filter did (counts and wall time of its stages).
struct FilterStats {
  std::size_t input_points = 0;    ///< points in the view
  std::size_t invalid_points = 0;  ///< NaN/Inf points (labelled non-ground, never used)
  /// Finite points outside the working volume (labelled non-ground, never used); see
  /// WorkingVolumeFilter. Always 0 for a filter that is not wrapped in one.
  std::size_t out_of_range_points = 0;
  /// Finite points within the working volume's min_range or body box (the vehicle's own
  /// returns; labelled non-ground, never used). Always 0 for a filter not wrapped in one.
  std::size_t near_points = 0;
  std::size_t ground_points = 0;  ///< points labelled ground
  double total_ms = 0.0;          ///< wall time of the whole call
  std::string backend;            ///< neighbour backend actually used ("" when not applicable)
  std::string note;               ///< e.g. the reason for a backend fallback; empty when none
  int threads = 1;                ///< worker threads the filter may use (`threads` resolved)
  /// The kind of scan this one was run as: "ground", "tls" (both the method's own steps) or
  /// "airborne" (the morphological surface); parameter scan_type. "" for a filter without one.
  std::string scan_type;
  std::string scan_reason;  ///< why: the parameter that set it, or what scan_type auto measured
  /// Named stage timings in milliseconds, in execution order.
  std::vector<std::pair<std::string, double>> stage_ms;
};

struct WorkingVolume;  // working_volume.h

/// \brief A ground segmentation algorithm: one label per input point.
///
/// Contract shared by all filters: `labels` is resized to `cloud.size()`; NaN/Inf points are
/// labelled kNonGround and never used by the algorithm; output is deterministic for a given input.
/// A filter object keeps scratch buffers between calls and is not thread-safe; use one per thread.
class GroundFilter {
 public:
  virtual ~GroundFilter() = default;
  /// \brief Labels every point of `cloud`; fills `stats` when not null.
  virtual void filter(const CloudView& cloud, std::vector<std::uint8_t>* labels,
                      FilterStats* stats = nullptr) = 0;
  /// \brief filter(), for a caller that needs every finite point inside `volume`
  ///        (WorkingVolumeFilter): a filter that takes the bounds of the points anyway can test
  ///        that there instead of the caller's own pass over the points.
  /// \return false (labels and stats unspecified) when a finite point may lie outside, or when
  ///         the filter does not test it (the default): the caller checks the points itself.
  virtual bool filterInside(const CloudView& /*cloud*/, const WorkingVolume& /*volume*/,
                            std::vector<std::uint8_t>* /*labels*/,
                            FilterStats* /*stats*/ = nullptr) {
    return false;
  }
  /// \brief The sensor origin in the view's frame (WorkingVolumeFilter::setOrigin passes its
  ///        centre on): scan_type auto looks at the points from there. Default: ignored.
  virtual void setSensorOrigin(float /*x*/, float /*y*/, float /*z*/) {}
  /// \brief True when scan_type finds no sensor at the origin of `cloud`: an airborne scan, or
  ///        a registered ground-level cloud (several sensor positions merged, a map tile). The
  ///        working volume then drops its max_range for this scan (such a cloud need not lie
  ///        near the origin). The decision holds for the next filter() call, also when that
  ///        gets only part of `cloud`. Default: false.
  virtual bool noSensorAtOrigin(const CloudView& /*cloud*/) { return false; }
  /// \brief Short method name ("voxel", "normal").
  virtual std::string name() const = 0;
};

/// \brief NAME=VALUE overrides for a filter's parameters (as given on a command line).
using ParamSettings = std::vector<std::pair<std::string, std::string>>;

/// \brief Names of the methods makeGroundFilter knows.
std::vector<std::string> groundFilterMethods();

/// \brief Creates the filter `method` with its defaults overridden by `settings`, wrapped in a
///        WorkingVolumeFilter (working_volume.h) around the view's origin.
///
/// Besides the method's own parameters, `settings` may hold `max_range` [m]: points farther
/// from the origin are labelled non-ground; `min_range` [m] and `body_box` ("[xmin, xmax, ymin,
/// ymax, zmin, zmax]" m) likewise exclude the sensor's own surroundings (WorkingVolume). Default 0
/// here (only the hard limit of 5 km per axis): files and benchmarks need not be sensor-centred;
/// the nodelets default to 1000 m. \throws std::invalid_argument for an unknown method, unknown
/// parameter or invalid value.
std::unique_ptr<GroundFilter> makeGroundFilter(const std::string& method,
                                               const ParamSettings& settings = {});

}  // namespace ground_filter

#endif  // GROUND_FILTER_GROUND_FILTER_H
