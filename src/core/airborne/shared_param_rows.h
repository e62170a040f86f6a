// Private to the core: the parameter-table rows that both methods' params structs share (the
// airborne mode's, MorphGroundParams) and the checks that go with them.
#ifndef GROUND_FILTER_SRC_CORE_AIRBORNE_SHARED_PARAM_ROWS_H
#define GROUND_FILTER_SRC_CORE_AIRBORNE_SHARED_PARAM_ROWS_H

#include <initializer_list>

#include "airborne/scan_type.h"
#include "ground_filter/param_table.h"
#include "ground_filter/params/param_def.h"

namespace ground_filter {

/// \brief A method's own rows followed by the rows every method has
///        (include/ground_filter/params/morph_params.def: the airborne morphological ground mode,
///        the same MorphGround stage in both filters, and scan_type, which picks that mode per
///        scan). P derives from MorphGroundParams.
template <typename P>
ParamTable<P> withSharedParamRows(std::initializer_list<ParamSpec<P>> own) {
  ParamTable<P> rows(own);
  rows.insert(rows.end(), {
#define GF_PARAM GF_PARAM_ROW
#include "ground_filter/params/morph_params.def"
#undef GF_PARAM
                          });
  return rows;
}

/// \brief The checks every method's validate() starts with: the range of each row of
///        P::table() and the value of scan_type (a shared row).
/// \throws std::invalid_argument naming the first bad parameter.
template <typename P>
void checkSharedParams(const P& p) {
  checkParamRanges(P::table(), p);
  validateScanTypeSetting(p.scan_type);
}

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_CORE_AIRBORNE_SHARED_PARAM_ROWS_H
