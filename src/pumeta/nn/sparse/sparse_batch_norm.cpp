#include "pumeta/nn/sparse/sparse_batch_norm.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

void add_batch_norm(ParamMap& params, ParamMap& buffers, const std::string& prefix,
                    int64_t channels) {
    for (auto [name, value] : {std::pair{".weight", 1.0}, std::pair{".bias", 0.0}})
        if (!params.emplace(prefix + name, at::full({channels}, value).requires_grad_(true))
                 .second)
            throw InternalError("parameter '" + prefix + name + "' initialised twice");
    for (auto [name, value] : {std::pair{".running_mean", 0.0}, std::pair{".running_var", 1.0}})
        if (!buffers.emplace(prefix + name, at::full({channels}, value)).second)
            throw InternalError("buffer '" + prefix + name + "' initialised twice");
}

at::Tensor sparse_batch_norm(const at::Tensor& x, const ParamMap& params, const std::string& prefix,
                             const BatchNormContext& context) {
    const at::Tensor& weight = param(params, prefix + ".weight");
    const at::Tensor& bias = param(params, prefix + ".bias");
    if (x.dim() != 2 || x.size(1) != weight.size(0))
        throw_input_error("sparse batch norm", "'{}' expects [M,{}] features, found {}", prefix,
                          weight.size(0), shape_string(x));
    at::Tensor mean, var;
    if (context.batch_statistics) {
        if (x.size(0) == 0) return x;
        mean = x.mean(0);
        at::Tensor centred = x - mean;
        var = (centred * centred).mean(0);
        // One site has no variance to estimate: it normalises to the bias and is not observed.
        if (context.observed && x.size(0) > 1) {
            const double m = double(x.size(0));
            (*context.observed)[prefix + ".running_mean"] = mean.detach().clone();
            (*context.observed)[prefix + ".running_var"] = var.detach() * (m / (m - 1));
        }
        return centred * at::rsqrt(var + context.eps) * weight + bias;
    }
    if (!context.running) throw InternalError("batch norm without running statistics");
    mean = param(*context.running, prefix + ".running_mean");
    var = param(*context.running, prefix + ".running_var");
    return (x - mean) * at::rsqrt(var + context.eps) * weight + bias;
}

void update_running_statistics(ParamMap& buffers, const ParamMap& observed, double momentum) {
    for (const auto& [name, value] : observed) {
        auto it = buffers.find(name);
        if (it == buffers.end()) throw InternalError("missing buffer '" + name + "'");
        it->second = it->second * (1.0 - momentum) + value.to(it->second.options()) * momentum;
    }
}

}  // namespace pumeta
