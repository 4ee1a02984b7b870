#include "pumeta/train/training_state.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta {

namespace {
const std::string kModel = "model/";
const std::string kOptim = "optim/";
const std::string kBuffers = "buffers/";
}  // namespace

void save_training_state(const std::string& path, const Backbone& model,
                         const ParamMap& optimizer, const nlohmann::json& info) {
    ParamMap tensors;
    for (const auto& [name, p] : model.parameters()) tensors[kModel + name] = p.detach();
    for (const auto& [name, b] : model.buffers()) tensors[kBuffers + name] = b;
    for (const auto& [name, t] : optimizer) tensors[kOptim + name] = t.detach();
    save_tensors(path, tensors, {{"kind", "training_state"},
                                 {"backbone", model.config()},
                                 {"info", info}});
}

TrainingState load_training_state(const std::string& path) {
    TensorFile file = load_tensors(path);
    if (file.extra.value("kind", "") != "training_state")
        throw_input_error(path, "not a training state file");
    TrainingState state;
    state.model = make_backbone(file.extra.at("backbone"));
    state.info = file.extra.at("info");
    for (auto& [name, p] : state.model->parameters()) {
        auto it = file.tensors.find(kModel + name);
        if (it == file.tensors.end())
            throw_input_error(path, "training state lacks parameter '{}'", name);
        if (!it->second.sizes().equals(p.sizes()))
            throw_input_error(path, "parameter '{}' has shape {} in the file", name,
                              fmt::format("{}", fmt::join(it->second.sizes(), "x")));
        at::NoGradGuard no_grad;
        p.copy_(it->second);
    }
    for (auto& [name, b] : state.model->buffers()) {
        auto it = file.tensors.find(kBuffers + name);
        if (it == file.tensors.end())
            throw_input_error(path, "training state lacks buffer '{}'", name);
        if (!it->second.sizes().equals(b.sizes()))
            throw_input_error(path, "buffer '{}' has shape {} in the file", name,
                              fmt::format("{}", fmt::join(it->second.sizes(), "x")));
        b = it->second.to(b.scalar_type());
    }
    for (auto& [name, t] : file.tensors)
        if (name.rfind(kOptim, 0) == 0) state.optimizer[name.substr(kOptim.size())] = t;
    return state;
}

}  // namespace pumeta
