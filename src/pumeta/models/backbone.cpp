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
    // The rebuild must hold every weight of the original, each of the same shape: a tensor
    // left out or reshaped would be a config_for_ratio that does not serve this ratio.
    auto share = [&](ParamMap& to, const ParamMap& from, const char* what) {
        if (to.size() != from.size())
            throw InternalError(fmt::format("{} at {}x: {} {} for the original's {}", model.name(),
                                            ratio, to.size(), what, from.size()));
        for (auto& [name, tensor] : to) {
            const at::Tensor& original = param(from, name);
            if (!tensor.sizes().equals(original.sizes()))
                throw InternalError(fmt::format("{} at {}x: {} '{}' has another shape",
                                                model.name(), ratio, what, name));
            tensor = original;
        }
    };
    share(rebuilt->parameters(), model.parameters(), "parameters");
    share(rebuilt->buffers(), model.buffers(), "buffers");
    return rebuilt;
}

}  // namespace pumeta
