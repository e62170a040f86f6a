// Forced include (-include) for linefit's ground_segmentation.cc with PCL 1.11 or newer
// (scripts/peers/CMakeLists.txt): its visualize branch makes PCL clouds with boost::make_shared,
// while a cloud's Ptr is std::shared_ptr since PCL 1.11. The branch never runs in the driver
// (visualize is false); this lets it compile.
#ifndef GROUND_FILTER_SCRIPTS_PEERS_LINEFIT_PCL_COMPAT_H
#define GROUND_FILTER_SCRIPTS_PEERS_LINEFIT_PCL_COMPAT_H

#include <memory>

namespace boost {
using std::make_shared;
}  // namespace boost

#endif  // GROUND_FILTER_SCRIPTS_PEERS_LINEFIT_PCL_COMPAT_H
