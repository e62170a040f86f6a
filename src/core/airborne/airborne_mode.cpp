#include "airborne/airborne_mode.h"

#include <algorithm>

namespace ground_filter {

void runAirborneMode(const CloudView& cloud, const MorphGroundSettings& s, MorphGround* morph,
                     Clock::time_point t_start, bool record_stage,
                     std::vector<std::uint8_t>* labels, FilterStats* st) {
  const auto t0 = Clock::now();
  st->invalid_points = cloud.size() - morph->run(cloud, s, labels);
  if (record_stage) st->stage_ms.emplace_back("morph", msSince(t0));
  st->ground_points = static_cast<std::size_t>(std::count(labels->begin(), labels->end(), 1));
  st->total_ms = msSince(t_start);
}

}  // namespace ground_filter
