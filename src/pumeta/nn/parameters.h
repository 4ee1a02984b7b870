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

/// A cap on the parameter and buffer elements that backbone constructors create on this
/// thread while it lives. Loading a checkpoint sets it to the elements the file stores, so
/// that a config asking for a larger network fails before it allocates, instead of a forged
/// "channels" taking all memory. Budgets do not nest.
class ParameterBudget {
  public:
    /// `source` names the input in the error (the checkpoint's path).
    ParameterBudget(int64_t elements, std::string source);
    ~ParameterBudget();
    ParameterBudget(const ParameterBudget&) = delete;
    ParameterBudget& operator=(const ParameterBudget&) = delete;
};

/// Takes the elements of a new parameter or buffer of `shape` from the active budget, before
/// it is allocated: InputError "<source>: ..." when they exceed what is left. No-op without a
/// budget. Every helper that creates parameters calls it.
void reserve_parameter(at::IntArrayRef shape);

}  // namespace pumeta
