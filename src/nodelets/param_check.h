#ifndef GROUND_FILTER_SRC_NODELETS_PARAM_CHECK_H
#define GROUND_FILTER_SRC_NODELETS_PARAM_CHECK_H

#include <ros/node_handle.h>  // XmlRpc::XmlRpcValue (from roscpp's xmlrpcpp)

#include <map>
#include <string>
#include <vector>

namespace ground_filter {

/// \brief One private parameter a nodelet knows: name, type and (numbers) range.
struct ParamCheck {
  enum class Type { kDouble, kInt, kBool, kString, kDoubleList };
  std::string name;
  Type type = Type::kDouble;
  bool ranged = false;  ///< min/max apply (dynamic_reconfigure numbers)
  double min = 0.0;
  double max = 0.0;
};

/// \brief The private parameters of the GroundFilterNodelet base (NodeletLazy's included), the
///        same for every leaf.
std::vector<ParamCheck> baseParamChecks();

/// \brief Checks the private parameters a user set (e.g. from a YAML, key relative to the
///        nodelet's namespace) against the known ones.
///
/// dynamic_reconfigure and NodeHandle::param() pass over an unknown key, keep their default for
/// a value of the wrong type and clamp one out of range, all without a word: this names each.
/// \return one message per refused key ("KEY: why"), in key order; the caller reports them and
///         removes those keys, so the defaults stay in use.
std::vector<std::string> checkPrivateParams(const std::map<std::string, XmlRpc::XmlRpcValue>& set,
                                            const std::vector<ParamCheck>& known,
                                            std::vector<std::string>* refused_keys);

}  // namespace ground_filter

#endif  // GROUND_FILTER_SRC_NODELETS_PARAM_CHECK_H
