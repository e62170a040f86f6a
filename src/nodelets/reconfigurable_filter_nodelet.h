#ifndef GROUND_FILTER_SRC_NODELETS_RECONFIGURABLE_FILTER_NODELET_H
#define GROUND_FILTER_SRC_NODELETS_RECONFIGURABLE_FILTER_NODELET_H

#include <dynamic_reconfigure/server.h>

#include <boost/any.hpp>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "ground_filter/working_volume.h"
#include "ground_filter_nodelet.h"
#include "param_check.h"
#include "params_from_config.h"

namespace ground_filter {

/// \brief A leaf's parameter plumbing, shared by every filter nodelet: a dynamic_reconfigure
///        server of `Config` whose accepted sets become `Filter(Params)`. A set that passes the
///        .cfg ranges but not `Params::validate()` is refused: the last good set stays in use and
///        is reported back to the client (the .cfg defaults when the first set is refused).
template <typename Config, typename Params, typename Filter>
class ReconfigurableFilterNodelet : public GroundFilterNodelet {
 protected:
  /// \brief Called with every accepted set before it is installed (e.g. a backend warning).
  virtual void onParamsAccepted(const Params& /*params*/) {}
  std::string methodName() const override { return Params::method(); }

  std::vector<ParamCheck> leafParams() const override {
    std::vector<ParamCheck> out;
    const Config lo = Config::__getMin__(), hi = Config::__getMax__();
    for (const auto& desc : Config::__getParamDescriptions__()) {
      ParamCheck c;
      c.name = desc->name;
      if (desc->type == "double" || desc->type == "int") {
        c.type = desc->type == "int" ? ParamCheck::Type::kInt : ParamCheck::Type::kDouble;
        boost::any a, b;
        desc->getValue(lo, a);
        desc->getValue(hi, b);
        c.ranged = true;
        c.min = desc->type == "int" ? boost::any_cast<int>(a) : boost::any_cast<double>(a);
        c.max = desc->type == "int" ? boost::any_cast<int>(b) : boost::any_cast<double>(b);
      } else {
        c.type = desc->type == "bool" ? ParamCheck::Type::kBool : ParamCheck::Type::kString;
      }
      out.push_back(c);
    }
    return out;
  }

  void onInitFilter() override {
    server_ = std::make_unique<dynamic_reconfigure::Server<Config>>(*pnh_);
    // The server calls back at once with the parameter-server values: that installs the filter.
    server_->setCallback([this](Config& config, uint32_t level) { reconfigure(config, level); });
  }

 private:
  void reconfigure(Config& config, uint32_t /*level*/) {
    // Every cfg field onto the params struct through its table (no validation).
    Params params = paramsFromConfigTable<Params>(config);
    WorkingVolume volume;
    volume.max_range = config.max_range;
    volume.min_range = config.min_range;
    volume.body_box = bodyBox();
    ObstacleBand band{config.obstacle_min_height, config.obstacle_max_height};
    try {
      params.validate();
      volume.validate();
      band.validate();
    } catch (const std::invalid_argument& e) {
      reportRejectedConfig(e.what());
      // The server publishes `config` after this returns: show what is really in use.
      if (have_good_) {
        config = last_good_;
        return;
      }
      config = Config::__getDefault__();  // the .cfg defaults are the library's
      params = paramsFromConfigTable<Params>(config);
      volume.max_range = config.max_range;
      volume.min_range = config.min_range;
      band = ObstacleBand{config.obstacle_min_height, config.obstacle_max_height};
      try {
        volume.validate();
      } catch (const std::invalid_argument&) {
        volume.body_box.clear();  // reported at start (checkParams)
      }
    }
    last_good_ = config;
    have_good_ = true;
    onParamsAccepted(params);
    setObstacleBand(band);
    setFilterFactory([params]() { return std::make_unique<Filter>(params); }, volume,
                     params.describe());
  }

  std::unique_ptr<dynamic_reconfigure::Server<Config>> server_;
  Config last_good_;  // reported back when a new set is refused
  bool have_good_ = false;
};

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_RECONFIGURABLE_FILTER_NODELET_H
