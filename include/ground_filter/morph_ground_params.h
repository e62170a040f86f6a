#ifndef GROUND_FILTER_MORPH_GROUND_PARAMS_H
#define GROUND_FILTER_MORPH_GROUND_PARAMS_H

#include <string>

namespace ground_filter {

/// \brief Parameters of the airborne mode, a base of both methods' params structs: the same
///        morphological ground stage (after SMRF) runs in either filter when morph_ground is
///        set, with the method's plane_distance as its height threshold on flat ground; and
///        scan_type, which picks the mode per scan (docs/scan_types.md).
struct MorphGroundParams {
  bool morph_ground = false;   ///< airborne: morphological ground surface [bool] (false)
  double morph_cell = 1.0;     ///< morph: raster cell edge [m] (1.0)
  double morph_slope = 0.1;    ///< morph: terrain slope the opening keeps, rise/run [1] (0.1)
  double morph_window = 18.0;  ///< morph: largest opening radius [m] (18)
  double morph_scale = 1.25;  ///< morph: plane_distance grows by this x surface gradient [m] (1.25)
  /// Scan kind: auto (decided per scan from the cloud) | ground | airborne | tls [enum] (auto).
  /// airborne runs the morph_* surface with plane_distance, at least 0.5 m, as its threshold;
  /// ground and tls the method's own steps; morph_ground true is airborne whatever this says.
  std::string scan_type = "auto";
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_MORPH_GROUND_PARAMS_H
