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
}

/// Removes a field of older model files whose only accepted value is the one pumeta keeps.
void drop_legacy_field(nlohmann::json& j, const char* key, const char* kept) {
    if (!j.is_object() || !j.contains(key)) return;
    if (j[key] != kept)
        throw_input_error("meta config", "{} '{}' is no longer supported (only \"{}\")", key,
                          j[key].dump(), kept);
    j.erase(key);
}

}  // namespace

InnerOptimizer parse_inner_optimizer(const std::string& name, const std::string& context) {
    if (name == "sgd") return InnerOptimizer::kSgd;
    if (name == "adam") return InnerOptimizer::kAdam;
    throw_input_error(context, "expected sgd or adam, found '{}'", name);
}

std::string to_string(InnerOptimizer optimizer) {
    return optimizer == InnerOptimizer::kAdam ? "adam" : "sgd";
}

bool InnerLoop::adapts(const std::string& name) const {
    if (adapt.empty()) return true;
    for (const std::string& prefix : adapt)
        if (name.rfind(prefix, 0) == 0) return true;
    return false;
}

MetaOptions MetaOptions::from_json(const nlohmann::json& j) {
    nlohmann::json current = j;
    drop_legacy_field(current, "outer_objective", "loss");
    drop_legacy_field(current, "inner_optimizer", "sgd");
    MetaOptions o;
    read_fields(current, "meta config", [&](auto&& visit) { visit_fields(o, visit); });
    o.check();
    return o;
}

void MetaOptions::check() const {
    if (inner_steps < 0) throw_input_error("meta config", "inner_steps must be >= 0");
    if (inner_lr < 0) throw_input_error("meta config", "inner_lr must be >= 0");
}

nlohmann::json MetaOptions::to_json() const {
    return write_fields([&](auto&& visit) { visit_fields(*this, visit); });
}

InnerLoop MetaOptions::inner_loop() const {
    InnerLoop loop;
    loop.steps = inner_steps;
    loop.step_size = inner_lr;
    loop.adapt = adapt;
    loop.first_order = first_order;
    return loop;
}

StepSizes make_step_sizes(const Backbone& model, const MetaOptions& options) {
    const InnerLoop loop = options.inner_loop();
    StepSizes sizes;
    for (const auto& [name, p] : model.parameters())
        if (loop.adapts(name))
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
               const at::Tensor& x, const InnerLoop& loop, const StepSizes& step_sizes,
               bool create_graph, std::vector<double>* losses) {
    if (loop.steps < 0 || !(loop.step_size >= 0))
        throw_input_error("inner loop", "steps ({}) and step size ({}) must be >= 0", loop.steps,
                          loop.step_size);
    const bool adam = loop.optimizer == InnerOptimizer::kAdam;
    if (adam && create_graph)
        throw_input_error("inner loop",
                          "Adam inner steps are for test-time adaptation only, not for "
                          "meta-training");
    if (adam && !step_sizes.empty())
        throw_input_error("--tta-optimizer",
                          "adam takes one learning rate (--tta-lr), not a meta-trained model's "
                          "per-tensor SGD step sizes");
    ParamMap fast = params;
    ParamMap adapting;
    for (const auto& [name, p] : fast)
        if (loop.adapts(name)) adapting[name] = p;
    if (!create_graph) {
        // Test-time adaptation: fresh leaves, so no graph reaches back to the stored model, and
        // copies for the adapting ones, which Adam updates in place.
        for (auto& [name, p] : fast) p = p.detach();
        for (auto& [name, p] : adapting) p = fast[name] = fast[name].clone().requires_grad_(true);
    }
    // Adam (fresh moments) updates the leaves in place; fast holds the same tensors.
    std::optional<Adam> optimizer;
    if (adam) optimizer.emplace(adapting, AdamOptions{loop.step_size});
    for (int64_t s = 0; s <= loop.steps; ++s) {
        bool last = s == loop.steps;
        if (last && !losses) break;
        at::Tensor loss = model.loss(x_down, x, fast);
        if (losses) losses->push_back(loss.item<double>());
        if (last) break;
        ParamMap grads = gradients(loss, adapting, create_graph && !loop.first_order);
        if (optimizer) {
            optimizer->step(grads);
            continue;
        }
        for (auto& [name, p] : adapting) {
            at::Tensor g = grads.at(name);
            auto alpha = step_sizes.find(name);
            at::Tensor next =
                alpha != step_sizes.end() ? p - alpha->second * g : p - loop.step_size * g;
            if (!create_graph) next = next.detach().requires_grad_(true);
            p = next;
            fast[name] = next;
        }
    }
    if (!create_graph)
        for (auto& [name, p] : fast) p = p.detach();
    return fast;
}

bool inner_loop_diverged(const std::vector<double>& losses) {
    return std::any_of(losses.begin(), losses.end(), [&](double v) {
        return !std::isfinite(v) || v > kDivergedInnerLoss * losses.front();
    });
}

MetaStepResult meta_gradient(const Backbone& model, const at::Tensor& x, const at::Tensor& y,
                             const MetaOptions& options, const StepSizes& step_sizes, uint64_t seed,
                             int64_t step) {
    options.check();
    const InnerLoop loop = options.inner_loop();
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
        ParamMap fast = adapt(model, theta, x_down, xn, loop, step_sizes,
                              /*create_graph=*/true, &inner);
        if (inner_loop_diverged(inner)) {
            spdlog::warn("meta step {} task {}: inner loop diverged (loss {}), task dropped", step,
                         n, fmt::join(inner, " -> "));
            ++result.dropped_tasks;
            continue;
        }
        at::Tensor outer = model.loss(xn, yn, fast, step);
        {
            at::NoGradGuard no_grad;
            outer_before += model.loss(xn, yn, theta, step).item<double>();
        }
        ParamMap wrt = theta;
        for (const auto& [name, a] : step_sizes) wrt["alpha/" + name] = a;
        ParamMap grads = gradients(outer, wrt);
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
