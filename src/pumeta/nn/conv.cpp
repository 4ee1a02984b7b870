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
    return {conv1x1_weights(x, central - message, bias), conv1x1_weights(x, message, {})};
}

at::Tensor conv1x1_weights(const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias) {
    if (weight.dim() != 2 || x.dim() < 1 || x.size(-1) != weight.size(1) ||
        (bias.defined() && (bias.dim() != 1 || bias.size(0) != weight.size(0))))
        throw_input_error("conv1x1", "weight {} and bias {} cannot map features of shape {}",
                          shape_string(weight), shape_string(bias), shape_string(x));
    // One (add)mm on the rows: at::linear on >2-D input runs matmul and a separate bias add.
    std::vector<int64_t> out_shape = x.sizes().vec();
    out_shape.back() = weight.size(0);
    at::Tensor rows = x.reshape({-1, x.size(-1)});
    at::Tensor out = bias.defined() ? at::addmm(bias, rows, weight.t()) : at::mm(rows, weight.t());
    // Not a view (like at::matmul's result), so in-place activations need no CopySlices.
    return at::_unsafe_view(out, out_shape);
}

at::Tensor conv1x1(const at::Tensor& x, const ParamMap& params, const std::string& prefix) {
    const at::Tensor& weight = weight_for(x, params, prefix + ".weight");
    auto bias = params.find(prefix + ".bias");
    return conv1x1_weights(x, weight, bias == params.end() ? at::Tensor() : bias->second);
}

void add_edge_conv(ParamMap& params, const std::string& prefix, int64_t in, int64_t out,
                   std::mt19937_64& rng) {
    add_xavier_uniform(params, prefix + ".central.weight", out, in, rng);
    add_linear(params, prefix + ".message", in, out, /*bias=*/true, rng);
}

at::Tensor edge_conv_edges(const at::Tensor& x, const at::Tensor& idx, const ParamMap& params,
                           const std::string& prefix) {
    EdgeTerms terms = edge_conv_terms(x, params, prefix);
    // In place: a gather's output is not needed by its backward, nor a sum's.
    return gather_neighbors(terms.message, idx).add_(terms.centre.unsqueeze(2)).relu_();
}

at::Tensor edge_conv(const at::Tensor& x, const at::Tensor& idx, const ParamMap& params,
                     const std::string& prefix) {
    EdgeTerms terms = edge_conv_terms(x, params, prefix);
    return (gather_max(terms.message, idx) + terms.centre).relu_();
}

}  // namespace pumeta
