#include "pumeta/nn/adam.h"

#include <ATen/ATen.h>

#include <cmath>

#include "pumeta/core/error.h"

namespace pumeta {

Adam::Adam(ParamMap& params, AdamOptions options) : params_(params), options_(options) {
    for (const auto& [name, p] : params_) {
        m_[name] = at::zeros_like(p, at::TensorOptions().requires_grad(false));
        v_[name] = at::zeros_like(p, at::TensorOptions().requires_grad(false));
    }
}

void Adam::step(const ParamMap& grads) {
    at::NoGradGuard no_grad;
    ++step_;
    double correction1 = 1 - std::pow(options_.beta1, step_);
    double correction2 = 1 - std::pow(options_.beta2, step_);
    double step_size = options_.lr / correction1;
    for (auto& [name, p] : params_) {
        auto it = grads.find(name);
        if (it == grads.end() || !it->second.defined()) continue;
        at::Tensor g = it->second;
        const auto found = groups_.find(name);
        const OptimizerGroup group = found == groups_.end() ? OptimizerGroup{} : found->second;
        const double scale = group.lr_scale;
        const double decay = options_.weight_decay + group.weight_decay;
        if (group.gradient_clip > 0) g = g.clamp(-group.gradient_clip, group.gradient_clip);
        if (decay != 0) g = g + decay * p;
        at::Tensor& m = m_.at(name);
        at::Tensor& v = v_.at(name);
        m.mul_(options_.beta1).add_(g, 1 - options_.beta1);
        v.mul_(options_.beta2).addcmul_(g, g, 1 - options_.beta2);
        at::Tensor denom = (v / correction2).sqrt_().add_(options_.eps);
        p.addcdiv_(m, denom, -step_size * scale);
    }
}

void Adam::set_group(const std::string& name, const OptimizerGroup& group) {
    if (!params_.count(name)) throw InternalError("Adam: no parameter '" + name + "'");
    groups_[name] = group;
}

void Adam::step() {
    ParamMap grads;
    for (auto& [name, p] : params_) grads[name] = p.grad();
    step(grads);
}

ParamMap Adam::state() const {
    ParamMap state;
    for (const auto& [name, m] : m_) state["m/" + name] = m;
    for (const auto& [name, v] : v_) state["v/" + name] = v;
    return state;
}

nlohmann::json Adam::state_info() const { return {{"step", step_}, {"lr", options_.lr}}; }

void Adam::load_state(const ParamMap& tensors, const nlohmann::json& info) {
    for (auto* moments : {&m_, &v_}) {
        const char* prefix = moments == &m_ ? "m/" : "v/";
        for (auto& [name, tensor] : *moments) {
            auto it = tensors.find(prefix + name);
            if (it == tensors.end())
                throw_input_error("optimiser state", "missing moment '{}{}'", prefix, name);
            if (!it->second.sizes().equals(tensor.sizes()))
                throw_input_error("optimiser state", "moment '{}{}' has the wrong shape", prefix,
                                  name);
            tensor = it->second.to(tensor.options()).clone();
        }
    }
    step_ = info.value("step", int64_t{0});
}

}  // namespace pumeta
