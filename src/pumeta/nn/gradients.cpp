#include "pumeta/nn/gradients.h"

#include <ATen/ATen.h>
#include <torch/csrc/autograd/autograd.h>

namespace pumeta {

ParamMap gradients(const at::Tensor& loss, const ParamMap& wrt, bool create_graph,
                   bool retain_graph) {
    std::vector<at::Tensor> inputs;
    inputs.reserve(wrt.size());
    for (const auto& [name, p] : wrt) inputs.push_back(p);
    // Argument order: outputs, inputs, grad_outputs, retain_graph, create_graph, allow_unused.
    std::vector<at::Tensor> grads = torch::autograd::grad(
        {loss}, inputs, {}, retain_graph || create_graph, create_graph, /*allow_unused=*/true);
    ParamMap result;
    size_t i = 0;
    for (const auto& [name, p] : wrt) {
        at::Tensor g = grads[i++];
        result[name] = g.defined() ? g : at::zeros_like(p);
    }
    return result;
}

ParamMap used_gradients(const at::Tensor& loss, const ParamMap& wrt) {
    std::vector<at::Tensor> inputs;
    inputs.reserve(wrt.size());
    for (const auto& [name, p] : wrt) inputs.push_back(p);
    std::vector<at::Tensor> grads = torch::autograd::grad({loss}, inputs, {}, false, false,
                                                          /*allow_unused=*/true);
    ParamMap result;
    size_t i = 0;
    for (const auto& [name, p] : wrt) {
        at::Tensor g = grads[i++];
        if (g.defined()) result[name] = g;
    }
    return result;
}

}  // namespace pumeta
