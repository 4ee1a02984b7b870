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

std::unique_ptr<Backbone> share_weights_at(const Backbone& model, int64_t ratio) {
    nlohmann::json config = model.config_for_ratio(ratio);
    if (config.is_null()) return nullptr;
    std::unique_ptr<Backbone> rebuilt = make_backbone(config);
    for (auto& [name, tensor] : rebuilt->parameters()) tensor = param(model.parameters(), name);
    for (auto& [name, tensor] : rebuilt->buffers()) tensor = param(model.buffers(), name);
    return rebuilt;
}

}  // namespace pumeta
