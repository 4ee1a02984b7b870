#include "pumeta/models/backbone.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"

namespace pumeta {

void Backbone::to(const std::string& device) {
    at::Device target(at::kCPU);
    try {
        target = at::Device(device);
    } catch (const c10::Error&) {
        throw_input_error("", "unknown device '{}'", device);
    }
    // Moving makes new leaves: anything holding the old tensors (an optimiser) must be rebuilt.
    for (auto& [name, tensor] : params_)
        if (tensor.device() != target) tensor = tensor.detach().to(target).requires_grad_(true);
    for (auto& [name, tensor] : buffers_) tensor = tensor.to(target);
}

}  // namespace pumeta
