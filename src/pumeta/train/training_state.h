// Everything a training or meta-training run needs to resume exactly: the model, the
// optimiser's tensors and a JSON of counters, in one checkpoint container (save_tensors).
#pragma once

#include <nlohmann/json.hpp>

#include <memory>
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
void save_training_state(const std::string& path, const Backbone& model,
                         const ParamMap& optimizer, const nlohmann::json& info);

/// Rebuilds the model from the stored config; InputError for a corrupted or foreign file.
TrainingState load_training_state(const std::string& path);

}  // namespace pumeta
