// Adam on a ParamMap, with state that checkpoints as plain tensors (so training and
// meta-training resume exactly) and no dependence on torch::optim's serialisation.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/nn/parameters.h"

namespace pumeta {

struct AdamOptions {
    double lr = 1e-3;
    double beta1 = 0.9;
    double beta2 = 0.999;
    double eps = 1e-8;
    double weight_decay = 0.0;
};

/// A parameter's treatment by Adam: its learning rate is the optimiser's times lr_scale,
/// weight_decay is added to the optimiser's own (L2 on the gradient) and its gradient may be
/// clipped element-wise.
struct OptimizerGroup {
    double lr_scale = 1.0;
    double weight_decay = 0.0;
    /// Each gradient value is clipped to [−gradient_clip, gradient_clip] first; 0: not.
    double gradient_clip = 0.0;
};

class Adam {
  public:
    Adam(ParamMap& params, AdamOptions options);

    /// One update from the gradients in `grads` (same names as the parameters; a missing or
    /// undefined gradient leaves its parameter unchanged). Parameters are updated in place.
    void step(const ParamMap& grads);
    /// One update from each parameter's .grad().
    void step();

    /// Puts parameter `name` in `group` (InternalError for an unknown name). Groups are not
    /// part of state(): whoever builds the optimiser sets them again on resume.
    void set_group(const std::string& name, const OptimizerGroup& group);

    void set_lr(double lr) { options_.lr = lr; }
    double lr() const { return options_.lr; }
    int64_t steps() const { return step_; }

    /// State as tensors ("m/<name>", "v/<name>") plus {"step": n} for checkpoints.
    ParamMap state() const;
    nlohmann::json state_info() const;
    /// Restores state(); InputError when names or shapes do not match the parameters.
    void load_state(const ParamMap& tensors, const nlohmann::json& info);

  private:
    ParamMap& params_;
    AdamOptions options_;
    ParamMap m_, v_;
    std::map<std::string, OptimizerGroup> groups_;
    int64_t step_ = 0;
};

}  // namespace pumeta
