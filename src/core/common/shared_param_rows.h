// Private to the core: parameter-table rows that both methods' params structs share.
#ifndef GROUND_FILTER_SRC_CORE_COMMON_SHARED_PARAM_ROWS_H
#define GROUND_FILTER_SRC_CORE_COMMON_SHARED_PARAM_ROWS_H

#include <initializer_list>

#include "ground_filter/param_table.h"

namespace ground_filter {

/// \brief A method's own rows followed by the rows every method has, in one place so their
///        ranges cannot drift apart: the airborne morphological ground mode (morph_*, the same
///        MorphGround stage in both filters), the worker threads and scan_type (which picks that
///        mode per scan). P needs the members named
///        below.
template <typename P>
ParamTable<P> withSharedParamRows(std::initializer_list<ParamSpec<P>> own) {
  ParamTable<P> rows(own);
  rows.insert(
      rows.end(),
      {
          {"morph_ground", &P::morph_ground, 0, 0, "bool",
           "airborne: morphological ground surface"},
          {"morph_cell", &P::morph_cell, 0.05, 100.0, "m", "morph: raster cell edge"},
          {"morph_slope", &P::morph_slope, 0.0, 10.0, "", "morph: slope kept by the opening"},
          {"morph_window", &P::morph_window, 0.1, 1000.0, "m", "morph: largest opening radius"},
          {"morph_scale", &P::morph_scale, 0.0, 100.0, "m", "morph: threshold per unit gradient"},
          {"threads", &P::threads, 0, 256, "threads", "worker threads, 0 = all cores"},
          {"scan_type", &P::scan_type, 0, 0, "enum", "auto | ground | airborne | tls"},
      });
  return rows;
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_COMMON_SHARED_PARAM_ROWS_H
