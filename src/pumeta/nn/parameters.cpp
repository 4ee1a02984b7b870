#include "pumeta/nn/parameters.h"

#include "pumeta/core/error.h"

namespace pumeta {

const at::Tensor& param(const ParamMap& params, const std::string& name) {
    auto it = params.find(name);
    if (it == params.end()) throw InternalError("missing parameter '" + name + "'");
    return it->second;
}

int64_t count_parameters(const ParamMap& params) {
    int64_t total = 0;
    for (const auto& [name, tensor] : params) total += tensor.numel();
    return total;
}

}  // namespace pumeta
