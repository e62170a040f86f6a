#ifndef GROUND_FILTER_SRC_NODELETS_NORMAL_GROUND_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_NORMAL_GROUND_FILTER_NODELET_H

#include <dynamic_reconfigure/server.h>

#include <memory>
#include <string>

#include "ground_filter/NormalGroundFilterConfig.h"
#include "ground_filter/normal_ground_filter.h"
#include "ground_filter_nodelet.h"

namespace ground_filter {

/// \brief Maps every dynamic_reconfigure field onto NormalGroundFilterParams (no validation).
NormalGroundFilterParams normalParamsFromConfig(const NormalGroundFilterConfig& config);

/// \brief One line "name=value ..." of all normal-vector parameters, for logs.
std::string describeNormalParams(const NormalGroundFilterParams& params);

/// \brief Nodelet `ground_filter/NormalGroundFilter`: the normal-vector method on
///        GroundFilterNodelet, parameters from cfg/NormalGroundFilter.cfg through
///        dynamic_reconfigure; `knn_backend` switches the neighbour search at run time.
class NormalGroundFilterNodelet : public GroundFilterNodelet {
 public:
  NormalGroundFilterNodelet();
  ~NormalGroundFilterNodelet() override;

 protected:
  void onInitFilter() override;
  std::string methodName() const override { return "normal"; }

 private:
  void reconfigure(NormalGroundFilterConfig& config, uint32_t level);

  std::unique_ptr<dynamic_reconfigure::Server<NormalGroundFilterConfig>> server_;
  NormalGroundFilterConfig last_good_;  // reported back when a new set is refused
  bool have_good_ = false;
  std::string warned_backend_;  // backend whose fallback was last warned about (one warning)
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_NORMAL_GROUND_FILTER_NODELET_H
