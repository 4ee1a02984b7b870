#include "pumeta/meta/maml.h"

#include <ATen/ATen.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <optional>

#include "pumeta/core/error.h"
#include "pumeta/core/json_fields.h"
#include "pumeta/nn/adam.h"
#include "pumeta/nn/gradients.h"

namespace pumeta {

namespace {

template <class Self, class Visit>
void visit_fields(Self& o, Visit&& visit) {
    visit("inner_steps", o.inner_steps);
    visit("inner_lr", o.inner_lr);
    visit("first_order", o.first_order);
    visit("learn_inner_lr", o.learn_inner_lr);
    visit("adapt", o.adapt);
    visit("outer_objective", o.outer_objective);
    visit("inner_optimizer", o.inner_optimizer);
}

}  // namespace

MetaOptions MetaOptions::from_json(const nlohmann::json& j) {
    MetaOptions o;
    read_fields(j, "meta config", [&](auto&& visit) { visit_fields(o, visit); });
    o.check();
    return o;
}

void MetaOptions::check() const {
    if (inner_steps < 0) throw_input_error("meta config", "inner_steps must be >= 0");
    if (inner_lr < 0) throw_input_error("meta config", "inner_lr must be >= 0");
    if (outer_objective != "loss" && outer_objective != "gain")
        throw_input_error("meta config", "outer_objective must be \"loss\" or \"gain\", found '{}'",
                          outer_objective);
    if (inner_optimizer != "sgd" && inner_optimizer != "adam")
        throw_input_error("meta config", "inner_optimizer must be \"sgd\" or \"adam\", found '{}'",
                          inner_optimizer);
}

nlohmann::json MetaOptions::to_json() const {
    return write_fields([&](auto&& visit) { visit_fields(*this, visit); });
}

bool MetaOptions::adapts(const std::string& name) const {
    if (adapt.empty()) return true;
    for (const std::string& prefix : adapt)
        if (name.rfind(prefix, 0) == 0) return true;
    return false;
}

StepSizes make_step_sizes(const Backbone& model, const MetaOptions& options) {
    StepSizes sizes;
    for (const auto& [name, p] : model.parameters())
        if (options.adapts(name))
            sizes[name] = at::full({}, options.inner_lr, p.options()).set_requires_grad(true);
    return sizes;
}

nlohmann::json step_sizes_to_json(const StepSizes& sizes) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [name, a] : sizes) j[name] = a.item<double>();
    return j;
}

StepSizes step_sizes_from_json(const nlohmann::json& j) {
    StepSizes sizes;
    for (const auto& [name, value] : j.items())
        sizes[name] = at::full({}, value.get<double>(), at::kFloat);
    return sizes;
}

ParamMap adapt(const Backbone& model, const ParamMap& params, const at::Tensor& x_down,
               const at::Tensor& x, const MetaOptions& options, const StepSizes& step_sizes,
               bool create_graph, std::vector<double>* losses) {
    options.check();
    const bool adam = options.inner_optimizer == "adam";
    if (adam && create_graph)
        throw_input_error("meta config",
                          "inner_optimizer \"adam\" is for test-time adaptation only, not for "
                          "meta-training");
    if (adam && !step_sizes.empty())
        throw_input_error("--tta-optimizer",
                          "adam takes one learning rate (--tta-lr), not a meta-trained model's "
                          "per-tensor SGD step sizes");
    ParamMap fast = params;
    ParamMap adapting;
    for (const auto& [name, p] : fast)
        if (options.adapts(name)) adapting[name] = p;
    if (!create_graph) {
        // Test-time adaptation: fresh leaves, so no graph reaches back to the stored model, and
        // copies for the adapting ones, which Adam updates in place.
        for (auto& [name, p] : fast) p = p.detach();
        for (auto& [name, p] : adapting) p = fast[name] = fast[name].clone().requires_grad_(true);
    }
    // Adam (fresh moments) updates the leaves in place; fast holds the same tensors.
    std::optional<Adam> optimizer;
    if (adam) optimizer.emplace(adapting, AdamOptions{options.inner_lr});
    for (int64_t s = 0; s <= options.inner_steps; ++s) {
        bool last = s == options.inner_steps;
        if (last && !losses) break;
        at::Tensor loss = model.loss(x_down, x, fast);
        if (losses) losses->push_back(loss.item<double>());
        if (last) break;
        ParamMap grads = gradients(loss, adapting, create_graph && !options.first_order);
        if (optimizer) {
            optimizer->step(grads);
            continue;
        }
        for (auto& [name, p] : adapting) {
            at::Tensor g = grads.at(name);
            auto alpha = step_sizes.find(name);
            at::Tensor next =
                alpha != step_sizes.end() ? p - alpha->second * g : p - options.inner_lr * g;
            if (!create_graph) next = next.detach().requires_grad_(true);
            p = next;
            fast[name] = next;
        }
    }
    if (!create_graph)
        for (auto& [name, p] : fast) p = p.detach();
    return fast;
}

std::vector<double> first_step_alignment(const Backbone& model, const ParamMap& params,
                                         const at::Tensor& x_down, const at::Tensor& x,
                                         const std::vector<SupervisedPair>& supervised,
                                         const MetaOptions& options, const StepSizes& step_sizes) {
    ParamMap fast, adapting;
    for (const auto& [name, p] : params) {
        fast[name] = p.detach();
        if (options.adapts(name)) adapting[name] = fast[name].requires_grad_(true);
    }
    // The first update: α ⊙ g for SGD; Adam's first bias-corrected step is α g / (|g| + ε).
    ParamMap update = gradients(model.loss(x_down, x, fast), adapting);
    for (auto& [name, g] : update) {
        if (options.inner_optimizer == "adam") g = g / (g.abs() + AdamOptions{}.eps);
        auto alpha = step_sizes.find(name);
        g = g *
            (alpha != step_sizes.end() ? alpha->second.detach().item<double>() : options.inner_lr);
    }
    double update_norm = 0;
    for (const auto& [name, u] : update) update_norm += u.square().sum().item<double>();
    std::vector<double> cosines;
    for (const SupervisedPair& pair : supervised) {
        ParamMap h = gradients(model.loss(pair.input, pair.target, fast), adapting);
        double dot = 0, norm = 0;
        for (const auto& [name, u] : update) {
            dot += (u * h.at(name)).sum().item<double>();
            norm += h.at(name).square().sum().item<double>();
        }
        cosines.push_back(update_norm == 0 || norm == 0 ? 0 : dot / std::sqrt(update_norm * norm));
    }
    return cosines;
}

MetaStepResult meta_gradient(const Backbone& model, const at::Tensor& x, const at::Tensor& y,
                             const MetaOptions& options, const StepSizes& step_sizes, uint64_t seed,
                             int64_t step) {
    options.check();
    const ParamMap& theta = model.parameters();
    int64_t tasks = x.size(0);
    MetaStepResult result;
    result.tasks = tasks;
    for (const auto& [name, p] : theta) result.grads[name] = at::zeros_like(p.detach());
    for (const auto& [name, a] : step_sizes)
        result.step_size_grads[name] = at::zeros_like(a.detach());
    double outer_before = 0;
    for (int64_t n = 0; n < tasks; ++n) {
        at::Tensor xn = x.slice(0, n, n + 1);
        at::Tensor yn = y.slice(0, n, n + 1);
        at::Tensor x_down = model.downsample(xn, seed + static_cast<uint64_t>(n));
        std::vector<double> inner;
        ParamMap fast = adapt(model, theta, x_down, xn, options, step_sizes,
                              /*create_graph=*/true, &inner);
        const bool diverged = std::any_of(inner.begin(), inner.end(), [&](double v) {
            return !std::isfinite(v) || v > kDivergedInnerLoss * inner.front();
        });
        if (diverged) {
            spdlog::warn("meta step {} task {}: inner loop diverged (loss {}), task dropped", step,
                         n, fmt::join(inner, " -> "));
            ++result.dropped_tasks;
            continue;
        }
        at::Tensor outer = model.loss(xn, yn, fast, step);
        at::Tensor objective = outer;
        if (options.outer_objective == "gain") {
            at::Tensor unadapted = model.loss(xn, yn, theta, step);
            outer_before += unadapted.item<double>();
            objective = outer - unadapted;
        } else {
            at::NoGradGuard no_grad;
            outer_before += model.loss(xn, yn, theta, step).item<double>();
        }
        ParamMap wrt = theta;
        for (const auto& [name, a] : step_sizes) wrt["alpha/" + name] = a;
        ParamMap grads = gradients(objective, wrt);
        for (auto& [name, g] : grads) {
            if (name.rfind("alpha/", 0) == 0)
                result.step_size_grads[name.substr(6)] += g;
            else
                result.grads[name] += g;
        }
        result.outer_loss += outer.item<double>();
        result.inner_loss_before += inner.front();
        result.inner_loss_after += inner.back();
    }
    // Means over the tasks kept (the paper's sum differs by a constant, docs/design.md).
    const int64_t kept = tasks - result.dropped_tasks;
    if (kept > 0) {
        const double scale = 1.0 / static_cast<double>(kept);
        for (auto& [name, g] : result.grads) g.mul_(scale);
        for (auto& [name, g] : result.step_size_grads) g.mul_(scale);
        result.outer_loss *= scale;
        result.outer_loss_before = outer_before * scale;
        result.inner_loss_before *= scale;
        result.inner_loss_after *= scale;
    }
    return result;
}

ParamMap pack_step_sum(const MetaStepResult& result, bool stop) {
    const double kept = static_cast<double>(result.tasks - result.dropped_tasks);
    const at::Tensor& like = result.grads.begin()->second;
    auto scalar = [&like](double v) { return at::scalar_tensor(v, like.options()); };
    ParamMap packet;
    for (const auto& [name, g] : result.grads) packet[name] = g * kept;
    for (const auto& [name, g] : result.step_size_grads) packet["alpha/" + name] = g * kept;
    packet["~outer_loss"] = scalar(result.outer_loss * kept);
    packet["~outer_loss_before"] = scalar(result.outer_loss_before * kept);
    packet["~inner_loss_before"] = scalar(result.inner_loss_before * kept);
    packet["~inner_loss_after"] = scalar(result.inner_loss_after * kept);
    packet["~tasks"] = scalar(static_cast<double>(result.tasks));
    packet["~dropped_tasks"] = scalar(static_cast<double>(result.dropped_tasks));
    packet["~stop"] = scalar(stop ? 1 : 0);
    return packet;
}

bool unpack_step_sum(const ParamMap& summed, MetaStepResult& result) {
    auto value = [&summed](const std::string& name) { return param(summed, name).item<double>(); };
    result.tasks = std::llround(value("~tasks"));
    result.dropped_tasks = std::llround(value("~dropped_tasks"));
    const int64_t kept = result.tasks - result.dropped_tasks;
    // Every task dropped everywhere: zero gradients, as meta_gradient() gives.
    const double scale = kept > 0 ? 1.0 / static_cast<double>(kept) : 0.0;
    for (auto& [name, g] : result.grads) g = param(summed, name) * scale;
    for (auto& [name, g] : result.step_size_grads) g = param(summed, "alpha/" + name) * scale;
    result.outer_loss = value("~outer_loss") * scale;
    result.outer_loss_before = value("~outer_loss_before") * scale;
    result.inner_loss_before = value("~inner_loss_before") * scale;
    result.inner_loss_after = value("~inner_loss_after") * scale;
    return value("~stop") > 0;
}

}  // namespace pumeta
