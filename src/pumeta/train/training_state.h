// Everything a training or meta-training run needs to resume exactly: the model, the
// optimiser's tensors and a JSON of counters, in one checkpoint container (save_tensors).
#pragma once

#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/models/backbone.h"
#include "pumeta/nn/parameters.h"

namespace pumeta {

struct TrainingState {
    std::unique_ptr<Backbone> model;
    ParamMap optimizer;
    nlohmann::json info;
};

/// Written atomically; model tensors under "model/", optimiser tensors under "optim/".
void save_training_state(const std::string& path, const Backbone& model, const ParamMap& optimizer,
                         const nlohmann::json& info);

/// Rebuilds the model from the stored config; InputError for a corrupted or foreign file.
TrainingState load_training_state(const std::string& path);

/// The start of a (meta-)training run in `run_dir`: with `resume` and a run_dir/state.ckpt,
/// that state (info["step"] says where); otherwise a fresh model from `make_fresh` with
/// empty info, and (when `writes`, i.e. on rank 0) the directory created and an old
/// log.jsonl removed. `what` names the command in log lines ("train", "meta-train").
TrainingState open_run(const std::string& run_dir, bool resume, bool writes,
                       const std::string& what,
                       const std::function<std::unique_ptr<Backbone>()>& make_fresh);

}  // namespace pumeta
