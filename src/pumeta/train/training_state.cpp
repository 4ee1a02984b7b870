#include "pumeta/train/training_state.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <filesystem>

#include "pumeta/core/error.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta {

namespace {
const std::string kModel = "model/";
const std::string kOptim = "optim/";
const std::string kBuffers = "buffers/";
}  // namespace

void save_training_state(const std::string& path, const Backbone& model, const ParamMap& optimizer,
                         const nlohmann::json& info) {
    ParamMap tensors;
    for (const auto& [name, p] : model.parameters()) tensors[kModel + name] = p.detach();
    for (const auto& [name, b] : model.buffers()) tensors[kBuffers + name] = b;
    for (const auto& [name, t] : optimizer) tensors[kOptim + name] = t.detach();
    save_tensors(path, tensors,
                 {{"kind", "training_state"}, {"backbone", model.config()}, {"info", info}});
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

TrainingState open_run(const std::string& run_dir, bool resume, bool writes,
                       const std::string& what,
                       const std::function<std::unique_ptr<Backbone>()>& make_fresh) {
    namespace fs = std::filesystem;
    if (writes) fs::create_directories(run_dir);
    fs::path state_file = fs::path(run_dir) / "state.ckpt";
    if (resume && fs::exists(state_file)) {
        TrainingState state = load_training_state(state_file.string());
        if (writes)
            spdlog::info("{}: resuming {} at step {}", what, run_dir,
                         state.info.value("step", int64_t{0}));
        return state;
    }
    if (resume && writes) spdlog::warn("{}: no state in {}; starting from scratch", what, run_dir);
    TrainingState fresh;
    fresh.model = make_fresh();
    if (writes) fs::remove(fs::path(run_dir) / "log.jsonl");
    return fresh;
}

}  // namespace pumeta
