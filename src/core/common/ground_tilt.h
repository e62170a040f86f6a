#ifndef GROUND_FILTER_SRC_CORE_COMMON_GROUND_TILT_H
#define GROUND_FILTER_SRC_CORE_COMMON_GROUND_TILT_H

#include <cstddef>
#include <string>
#include <vector>

#include "ground_filter/cloud_view.h"

namespace ground_filter {

/// \brief The ground around a sensor, as a plane through the lowest point of each 1 m column
///        within kRadius of it: its normal, and how far it leans from the frame's z.
struct GroundTilt {
  bool found = false;                  ///< a plane with enough support was found
  double normal[3] = {0.0, 0.0, 1.0};  ///< unit normal, z >= 0
  double tilt_deg = 0.0;               ///< angle between normal and the frame's z [deg]
  std::size_t columns = 0;             ///< occupied columns fitted (within kRadius; the ring)
  std::size_t inliers = 0;             ///< columns whose lowest point lies on the plane
  double height = 0.0;                 ///< the sensor's height above the plane [m]
  /// This plane is the farther ring's (kRadius to kFarRadius): the sensor stood more than
  /// kMaxHeight above the near plane, or the near plane would have turned the scan while the
  /// ring's lies kBelowNear lower and level.
  bool high = false;
  /// \brief A plane was found and leans `level_tilt` or more: the scan is to be turned.
  bool turns(double level_tilt) const { return found && tilt_deg >= level_tilt; }
};

/// \brief Finds how far a single scan's frame leans from the ground around its sensor (a
///        sensor mounted tilted, with no gravity frame to undo it), and levels the scan.
///
/// The ground a sensor stands over is the surface most of the lowest points of the columns
/// around it lie on: a deterministic RANSAC over those lowest points (planes leaning at most
/// kMaxTilt, passing below the sensor), refined by least squares over its inliers.
class GroundTiltEstimator {
 public:
  static constexpr double kRadius = 15.0;  ///< columns within this of the sensor [m]
  static constexpr double kNear = 1.5;     ///< and beyond this (the vehicle itself) [m]
  static constexpr double kColumn = 1.0;   ///< column edge [m]
  static constexpr double kBand = 0.25;    ///< a lowest point on the plane: within this [m]
  /// Planes leaning more than this are walls or cliffs, never the ground under the sensor; a
  /// mount leaning up to it is levelled (handheld and backpack rigs: 30-45 deg) [deg]. 35 lost
  /// every 45 deg mount; 55-75 take the generated mounts of up to 54 deg and change no level
  /// scan (dev data, generated scenes, the sensor sweep).
  static constexpr double kMaxTilt = 60.0;
  /// The plane passes at most this far above the origin: the sensor, or in a frame on the
  /// ground below it (base_link) that ground; a ceiling lies higher [m].
  static constexpr double kAbove = 0.3;
  /// A sensor higher than this above the plane of its near columns (a mast, a pole, a truck's
  /// roof) sees the ground only from far out: when level, its lowest points within kRadius
  /// lie where its lowest beam meets walls and cars (that beam's cone) or on a thin ring of
  /// terrain, whose lean is not the mount's. Its lean is read from the ring kRadius to
  /// kFarRadius instead, which it sees as a car's sensor sees its near ground [m].
  static constexpr double kMaxHeight = 3.0;
  /// Outer edge of that farther ring: 25-50 m give the same F1 on 63 generated scans 4.5-7 m
  /// up, level or pitched 10-20 deg; 60 m less [m].
  static constexpr double kFarRadius = 40.0;
  static constexpr double kFarColumn = 2.0;  ///< its column edge [m]
  /// A near plane that would turn the scan is checked against that farther ring: where the
  /// ring's plane passes this much farther below the sensor, the near columns' lowest points
  /// lie on car roofs, crowns and walls over ground the sensor sees only farther out (a sensor
  /// 3 m or more up with a narrow vertical field: a lowest beam of -10 deg meets the ground
  /// 17 m out), and the ring's plane decides [m].
  static constexpr double kBelowNear = 1.0;
  static constexpr double kMinShare = 0.2;        ///< inliers: at least this share of the columns
  static constexpr std::size_t kMinInliers = 30;  ///< and at least this many
  static constexpr int kHypotheses = 200;         ///< RANSAC draws
  static constexpr std::size_t kSample = 16384;   ///< points read, about (every n-th)

  /// \brief The check applies: `level_tilt` > 0 and a single scan (not `registered`) whose
  ///        sensor, `origin`, is finite.
  static bool applies(double level_tilt, bool registered, const float origin[3]);
  /// \brief Appends "the ground around the sensor leans ... the scan was turned onto it" to
  ///        `note` ("; " first unless it is empty).
  static void appendTurnNote(double tilt_deg, double level_tilt, std::string* note);

  /// \brief The ground plane around `origin` (the sensor) in `cloud`'s frame; a near plane
  ///        leaning `level_tilt` or more is checked against the farther ring (kBelowNear).
  GroundTilt estimate(const CloudView& cloud, const float origin[3], double level_tilt);

  /// \brief Writes `cloud` turned about `origin` so that `tilt.normal` becomes the z axis (the
  ///        smallest rotation) into `xyz` (packed x y z, input order; non-finite points as they
  ///        are). \return a view of `xyz`.
  static CloudView level(const CloudView& cloud, const float origin[3], const GroundTilt& tilt,
                         std::vector<float>* xyz);

 private:
  // The plane through the lowest points of the columns from `near` to `radius` of the origin.
  GroundTilt fitLowest(const CloudView& cloud, const float origin[3], double near, double radius,
                       double column);

  std::vector<float> low_;  // per column: lowest x, y, z relative to the origin (z: +inf none)
  std::vector<float> pts_;  // the occupied columns' lowest points
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_GROUND_TILT_H
