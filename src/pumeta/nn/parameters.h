// Named parameters: the currency between backbones, optimisers and MAML's fast weights.
#pragma once

#include <ATen/core/Tensor.h>

#include <map>
#include <string>

namespace pumeta {

/// name -> tensor. Names are stable ("head.conv.weight") and become checkpoint keys.
/// Ordered so that iteration (and so serialisation and gradient lists) is deterministic.
using ParamMap = std::map<std::string, at::Tensor>;

/// Looks up `name`; InternalError naming the missing key when absent.
const at::Tensor& param(const ParamMap& params, const std::string& name);

/// Total number of scalar elements.
int64_t count_parameters(const ParamMap& params);

}  // namespace pumeta
