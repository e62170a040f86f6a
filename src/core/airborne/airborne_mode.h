#ifndef GROUND_FILTER_SRC_CORE_AIRBORNE_AIRBORNE_MODE_H
#define GROUND_FILTER_SRC_CORE_AIRBORNE_AIRBORNE_MODE_H

#include <cstdint>
#include <vector>

#include "airborne/morph_ground.h"
#include "common/threads_timing.h"
#include "ground_filter/cloud_view.h"
#include "ground_filter/ground_filter.h"

namespace ground_filter {

/// \brief The airborne mode of both methods, in one place: labels every point of `cloud` with
///        the morphological ground surface (`morph`, settings `s`) and fills `st`'s invalid and
///        ground counts and total time (from `t_start`); the "morph" stage time too when
///        `record_stage` (a caller without stats skips it: nothing allocated).
void runAirborneMode(const CloudView& cloud, const MorphGroundSettings& s, MorphGround* morph,
                     Clock::time_point t_start, bool record_stage,
                     std::vector<std::uint8_t>* labels, FilterStats* st);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_AIRBORNE_AIRBORNE_MODE_H
