// Private to the core: which kind of scan a cloud is (the `scan_type` parameter of both
// methods) and the mode it runs in.
#ifndef GROUND_FILTER_SRC_CORE_AIRBORNE_SCAN_TYPE_H
#define GROUND_FILTER_SRC_CORE_AIRBORNE_SCAN_TYPE_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "airborne/morph_ground.h"
#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief The kinds of scan the filters tell apart.
enum class ScanType {
  kGround,    ///< ground-level sensor (vehicle, robot): the method's own ground model
  kTls,       ///< terrestrial scanner on a tripod: a ground-level scan, same mode as kGround
  kAirborne,  ///< airborne / nadir (survey tile, drone): the morphological ground surface
};

/// \brief "ground", "tls" or "airborne".
const char* scanTypeName(ScanType type);

/// \brief Values of the `scan_type` parameter: "auto" (decide per scan), "ground", "airborne",
///        "tls", "registered" (a ground-level cloud with no sensor at its origin) (force one).
const std::vector<std::string>& scanTypeSettings();

/// \brief Checks a `scan_type` value.
/// \throws std::invalid_argument naming the parameter, the value and the known values.
void validateScanTypeSetting(const std::string& value);

/// \brief A decision: the type and why (for FilterStats and the eval tool).
struct ScanDecision {
  ScanType type = ScanType::kGround;
  /// A ground-level cloud with no single sensor at its origin (rule 4: registered sweeps or
  /// stations, a map tile): max_range does not cut it.
  bool registered = false;
  /// Registered by rule 4 alone (a side view's density pattern, no far origin): the one reading
  /// of `registered` that a cloud fully seen from its origin overrides (the normal method's
  /// plane rule; OriginView).
  bool side_view = false;
  std::string reason;
  /// Share of the sampled points below the origin's height (auto; 1 where the user set the
  /// scan type): an origin with almost none below it is no sensor above the ground (the voxel
  /// method's start segment).
  double below_share = 1.0;
  /// x/y distance of the densest sampled cell's centre from the origin [m] (auto; 0 where the
  /// user set the scan type): a spinning sensor's points are densest around it, so a far one
  /// shows a sensor away from the origin (the voxel method's start segment).
  double densest_offset = 0.0;
};

/// \brief What scan_type auto measures on a cloud (ScanTypeClassifier::measure()).
struct ScanMeasures {
  std::size_t sampled = 0;      ///< valid points looked at (every step-th valid point)
  double cell = 0.0;            ///< edge of the xy cells [m]
  std::size_t cells = 0;        ///< occupied cells
  double top_share = 0.0;       ///< share of the points in the densest tenth of the cells
  double below_share = 0.0;     ///< share of the points below the origin's height
  double steep_share = 0.0;     ///< share of the points >= 45 deg below the origin
  double steep_depth = 0.0;     ///< median depth of those below the origin [m]
  double high_share = 0.0;      ///< share of the points >= 30 deg above the origin
  double extent = 0.0;          ///< larger side of the (1-99 % trimmed) xy box [m]
  double nearest = 0.0;         ///< distance of the nearest sampled point from the origin [m]
  double densest_offset = 0.0;  ///< x/y distance of the densest cell's centre from the origin
  // Rule 4 (docs/scan_types.md): the same density pattern in 1 m columns over a bounded read.
  std::size_t read = 0;           ///< valid points read for the columns (at most kMaxRead)
  std::size_t columns = 0;        ///< occupied kColumn x kColumn columns
  double column_mean = 0.0;       ///< read points per occupied column
  double column_top_share = 0.0;  ///< share of the read points in the densest tenth of columns
  /// Points behind nearer ones seen from the origin (OriginView; measure() only: the normal
  /// method's sensor rule reads it, not the scan type).
  double hidden_share = 0.0;
};

/// \brief scan_type auto: tells a ground-level scan from an airborne one by where its points
///        lie, from the cloud alone (docs/scan_types.md).
///
/// The rule: a sensor on the ground sees the ground ever more obliquely with range, so the
/// points per m2 fall steeply with the distance from it (about 1/r^3 for a spinning LiDAR's
/// rings): a tenth of the xy cells of the scan (those near the sensor) holds most points. A
/// nadir scanner (aircraft, drone) samples the ground at a nearly even spacing: the densest
/// tenth of the cells holds little more than a tenth of the points. Frame-free: a survey tile
/// in map coordinates, whose origin is no sensor, is judged like one centred on its sensor.
/// A second rule looks from the origin: when most points lie at least 45 deg below it and many
/// metres down, the origin is a sensor looking down on them (a drone), unless the 1 m columns
/// hold a side view (a map tile registered below its frame's origin).
/// Deterministic; looks at up to kMaxSamples evenly spread points (about 0.1 ms).
class ScanTypeClassifier {
 public:
  /// \brief At most this many points are looked at.
  static constexpr std::size_t kMaxSamples = 8192;
  /// \brief Fewer valid points: too few to judge, the default (ground-level) mode.
  static constexpr std::size_t kMinPoints = 64;
  /// \brief A footprint smaller than this [m] is too small to judge (ground-level mode).
  static constexpr double kMinExtent = 2.0;
  /// \brief Ground-level when the densest tenth of the cells holds at least this share.
  static constexpr double kConcentrated = 0.4;
  /// \brief A nadir view: at least this share of the points 45 deg or more below the origin...
  static constexpr double kSteepShare = 0.5;
  /// \brief ...whose median depth below it is at least this [m] (above any mast or tripod).
  static constexpr double kNadirDepth = 8.0;
  /// \brief A tripod scanner: at least this share of the points 30 deg or more above the origin
  ///        (beyond the field of view of a vehicle's LiDAR); reported only, same mode as ground.
  static constexpr double kTlsHighShare = 0.03;
  /// \brief A ground-level scan with no sampled point within this of the origin [m] was
  ///        exported in map coordinates (a ground-level sensor always sees the ground within
  ///        metres of itself): registered, no range cut.
  static constexpr double kFarOrigin = 100.0;
  /// \brief Rule 4 reads at most this many points, evenly spread (memory and time stop
  ///        growing with the cloud past it).
  static constexpr std::size_t kMaxRead = 1048576;
  /// \brief Rule 4's read where rule 2 finds a nadir view (a drone's stream meets it on every
  ///        scan): 16 points a column or more over 4,096 m2, a 64 m map tile.
  static constexpr std::size_t kNadirRead = 65536;
  /// \brief Rule 4 counts the points of each column in an array where the box holds at most
  ///        this many columns (1 M: 4 MiB, 1 km x 1 km), else it sorts the read's columns.
  static constexpr std::uint64_t kDenseColumns = std::uint64_t{1} << 20;
  /// \brief Edge of rule 4's columns [m]: the scale of a side view's near field and walls.
  static constexpr double kColumn = 1.0;
  /// \brief Rule 4 judges only where the read holds at least this many points per occupied
  ///        column on average (below it, counts of an even sampling scatter too much).
  static constexpr double kMinColumnMean = 4.0;
  /// \brief Rule 4: ground-level when the densest tenth of the columns holds at least this.
  static constexpr double kColumnConcentrated = 0.32;
  /// \brief Room for the longest reason [chars]: reserved once, so a stream of scans allocates
  ///        nothing after the first.
  static constexpr std::size_t kReasonRoom = 512;

  /// \brief The measures behind the decision (origin: the sensor origin in the view's frame),
  ///        the side-view columns included (classify() reads those only when it needs them).
  ScanMeasures measure(const CloudView& cloud, const float origin[3]);
  /// \brief Decides the type of `cloud` and says why, into `d` (its reason string is reused:
  ///        no allocation after the first scan).
  void classify(const CloudView& cloud, const float origin[3], ScanDecision* d);

 private:
  std::vector<float> xs_, ys_, tmp_;  // sampled points
  std::vector<float> zs_, depth_;
  std::vector<std::uint32_t> counts_;
  std::vector<std::uint64_t> keys_;   // column of each point read by rule 4
  std::vector<std::uint32_t> dense_;  // points per column of a box of at most kDenseColumns

  float box_[4] = {0.f, 0.f, 0.f, 0.f};  // trimmed xy box: x0 x1 y0 y1

  // Rules 1-3's measures (the sample, its cells, the view from the origin); keeps the box.
  ScanMeasures measureSample(const CloudView& cloud, const float origin[3]);
  // Rule 4's measures over the box kept by measureSample().
  void measureColumns(const CloudView& cloud, ScanMeasures* m, std::size_t most);
};

/// \brief Both methods' switch between their ground-level mode and the airborne one: resolves
///        `scan_type` (and the older `morph_ground`) per scan, keeps the sensor origin, and can
///        keep a decision that the working volume asked for before the filter runs.
class ScanTypeSwitch {
 public:
  /// \brief `setting` one of scanTypeSettings(); `morph_ground` forces the airborne mode.
  ScanTypeSwitch(const std::string& setting, bool morph_ground);
  /// \brief The sensor origin in the views' frame (default 0, 0, 0).
  void setOrigin(float x, float y, float z);
  /// \brief The sensor origin set last (x, y, z).
  const float* origin() const { return origin_; }
  /// \brief Decides for `cloud` and keeps the decision for the next decide() (whatever view it
  ///        gets: the working volume may hand on only the points inside it); a decision kept
  ///        already is returned as it is (the same scan, asked twice before it runs).
  const ScanDecision& pin(const CloudView& cloud);
  /// \brief The decision for `cloud`: the one pin() kept (used once), else a new one.
  const ScanDecision& decide(const CloudView& cloud);
  /// \brief True when decisions are made per scan (scan_type auto, morph_ground off).
  bool automatic() const { return automatic_; }

 private:
  bool automatic_ = true;
  bool pinned_ = false;
  float origin_[3] = {0.f, 0.f, 0.f};
  ScanDecision fixed_, last_;
  ScanTypeClassifier classifier_;
};

/// \brief Least height threshold of the airborne mode that scan_type picks [m]: SMRF's
///        published 0.5 m (an airborne return's height is uncertain by decimetres: ranging,
///        GNSS/IMU, a footprint of decimetres on slopes and crowns). The ground-level default
///        plane_distance (0.15 m) is below it.
constexpr double kAirborneMinThreshold = 0.5;

/// \brief The morphological surface's settings of the airborne mode: the morph_* fields and
///        plane_distance as the threshold; at least kAirborneMinThreshold unless morph_ground
///        is set (then plane_distance as given, as the presets do).
template <class P>
MorphGroundSettings airborneSettings(const P& p) {
  const double t = p.morph_ground || p.plane_distance > kAirborneMinThreshold
                       ? p.plane_distance
                       : kAirborneMinThreshold;
  return MorphGroundSettings{p.morph_cell, p.morph_slope, p.morph_window, t, p.morph_scale};
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_AIRBORNE_SCAN_TYPE_H
