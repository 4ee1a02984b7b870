#include "pumeta/nn/conv.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/nn/graph.h"
#include "pumeta/nn/init.h"

namespace pumeta {

namespace {

const at::Tensor& weight_for(const at::Tensor& x, const ParamMap& params, const std::string& name) {
    const at::Tensor& weight = param(params, name);
    if (weight.dim() != 2 || x.dim() < 1 || x.size(-1) != weight.size(1))
        throw_input_error(name, "weight of shape {} cannot map features of shape {}",
                          shape_string(weight), shape_string(x));
    return weight;
}

}  // namespace

EdgeTerms edge_conv_terms(const at::Tensor& x, const ParamMap& params, const std::string& prefix) {
    const at::Tensor& central = weight_for(x, params, prefix + ".central.weight");
    const at::Tensor& message = weight_for(x, params, prefix + ".message.weight");
    const at::Tensor& bias = param(params, prefix + ".message.bias");
    return {at::linear(x, central - message, bias), at::linear(x, message)};
}

at::Tensor conv1x1(const at::Tensor& x, const ParamMap& params, const std::string& prefix) {
    const at::Tensor& weight = weight_for(x, params, prefix + ".weight");
    auto bias = params.find(prefix + ".bias");
    return bias == params.end() ? at::linear(x, weight) : at::linear(x, weight, bias->second);
}

void add_edge_conv(ParamMap& params, const std::string& prefix, int64_t in, int64_t out,
                   std::mt19937_64& rng) {
    add_xavier_uniform(params, prefix + ".central.weight", out, in, rng);
    add_linear(params, prefix + ".message", in, out, /*bias=*/true, rng);
}

at::Tensor edge_conv_edges(const at::Tensor& x, const at::Tensor& idx, const ParamMap& params,
                           const std::string& prefix) {
    EdgeTerms terms = edge_conv_terms(x, params, prefix);
    return at::relu(gather_neighbors(terms.message, idx) + terms.centre.unsqueeze(2));
}

at::Tensor edge_conv(const at::Tensor& x, const at::Tensor& idx, const ParamMap& params,
                     const std::string& prefix) {
    EdgeTerms terms = edge_conv_terms(x, params, prefix);
    return at::relu(gather_max(terms.message, idx) + terms.centre);
}

}  // namespace pumeta
