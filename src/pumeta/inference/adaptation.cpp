#include "pumeta/inference/adaptation.h"

#include <spdlog/spdlog.h>

#include "pumeta/core/error.h"

namespace pumeta {

AdaptationUnit parse_adaptation_unit(const std::string& name, const std::string& context) {
    if (name == "object") return AdaptationUnit::kObject;
    if (name == "patch") return AdaptationUnit::kPatch;
    if (name == "cloud") return AdaptationUnit::kCloud;
    throw_input_error(context, "expected object, patch or cloud, found '{}'", name);
}

std::string to_string(AdaptationUnit unit) {
    switch (unit) {
        case AdaptationUnit::kObject:
            return "object";
        case AdaptationUnit::kPatch:
            return "patch";
        case AdaptationUnit::kCloud:
            return "cloud";
    }
    return "object";
}

nlohmann::json Adaptation::to_json() const {
    return {
        {"steps", inner.steps},
        {"unit", to_string(unit)},
        {"optimizer", to_string(inner.optimizer)},
        {"lr", step_sizes.empty() ? nlohmann::json(inner.step_size) : nlohmann::json("learned")}};
}

Adaptation stored_adaptation(const nlohmann::json& meta, const nlohmann::json& step_sizes) {
    Adaptation adaptation;
    adaptation.inner.step_size = MetaOptions().inner_lr;
    if (meta.is_null()) return adaptation;
    adaptation.inner = MetaOptions::from_json(meta).inner_loop();
    // Test-time adaptation never differentiates through its steps.
    adaptation.inner.first_order = false;
    if (!step_sizes.is_null()) adaptation.step_sizes = step_sizes_from_json(step_sizes);
    return adaptation;
}

Adaptation adaptation_for(const Adaptation& defaults, bool meta_trained,
                          const AdaptationOverrides& overrides) {
    Adaptation a = defaults;
    if (overrides.steps) a.inner.steps = *overrides.steps;
    if (overrides.step_size) {
        a.inner.step_size = *overrides.step_size;
        a.step_sizes.clear();
    }
    if (overrides.unit) a.unit = *overrides.unit;
    if (overrides.downsampler) a.downsampler = overrides.downsampler;
    if (overrides.optimizer) a.inner.optimizer = *overrides.optimizer;
    if (a.inner.optimizer == InnerOptimizer::kAdam && !a.step_sizes.empty())
        throw_input_error("--tta-optimizer",
                          "adam takes one learning rate (--tta-lr), not a meta-trained model's "
                          "per-tensor SGD step sizes");
    if (a.enabled() && !meta_trained && !overrides.step_size)
        spdlog::warn(
            "--tta-steps without --tta-lr on a model that is not meta-trained: using "
            "inner_lr {}",
            a.inner.step_size);
    return a;
}

}  // namespace pumeta
