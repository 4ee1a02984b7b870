// Test-time adaptation (paper Algorithm 2) as one value: built once by adaptation_for() from
// the model file's stored defaults and the user's overrides, then passed as is to the
// pipeline (UpsampleOptions::adaptation).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "pumeta/data/patch_set.h"
#include "pumeta/meta/maml.h"

namespace pumeta {

/// What one θ' adapts on (docs/design.md, "Inference").
enum class AdaptationUnit {
    /// One adaptation on all patches of the input (a batch), θ' used for every patch, each
    /// patch's X↓ its own downsample.
    kObject,
    /// Each patch adapts on its own.
    kPatch,
    /// One θ' from X↓ = the downsampled whole cloud, cut into network-sized patches paired
    /// with the points of X around them.
    kCloud,
};
/// "object", "patch" or "cloud"; InputError naming `context` otherwise.
AdaptationUnit parse_adaptation_unit(const std::string& name, const std::string& context);
std::string to_string(AdaptationUnit unit);

struct Adaptation {
    /// Steps (inner.steps = 0: the plain backbone), step size, adapting parameters, optimiser.
    InnerLoop inner{/*steps=*/0};
    /// Meta-SGD's learned per-tensor step sizes (0-dim tensors by parameter name) of a
    /// meta-trained model; empty: inner.step_size for every adapting tensor.
    StepSizes step_sizes;
    AdaptationUnit unit = AdaptationUnit::kObject;
    /// X↓'s sampler; empty: the backbone's training-pair downsampler. E.g. kFps makes X↓ of a
    /// blue-noise input blue-noise too.
    std::optional<InputSampler> downsampler;
    /// The one-θ' units' inner loss uses at most this many patches (a seeded subset), so that
    /// adaptation cost stays bounded on huge inputs.
    int64_t max_patches = 64;

    bool enabled() const { return inner.steps > 0; }
    /// For summaries: {"steps", "unit", "optimizer", "lr": α or "learned (per tensor)"}.
    nlohmann::json to_json() const;
};

/// What a user asks of adaptation; an unset field keeps the model's default.
struct AdaptationOverrides {
    std::optional<int64_t> steps;
    /// One step size for every adapting tensor, in place of learned ones.
    std::optional<double> step_size;
    std::optional<AdaptationUnit> unit;
    std::optional<InputSampler> downsampler;
    std::optional<InnerOptimizer> optimizer;
};

/// A model file's adaptation defaults: a meta-trained model's N, α (or its learned step sizes)
/// and adapting parameters; a plain model does not adapt (0 steps, α = MetaOptions' default).
/// `meta` is the "meta" object a meta-trained checkpoint stores, `step_sizes` its
/// "step_sizes" (null when absent).
Adaptation stored_adaptation(const nlohmann::json& meta, const nlohmann::json& step_sizes);

/// `defaults` with `overrides` applied: a given step size replaces the learned ones. InputError
/// for Adam with learned per-tensor step sizes (Adam takes one learning rate). `meta_trained`
/// says whether the defaults came from a meta-trained model: adapting a plain one without a
/// step size warns that α is MetaOptions' default.
Adaptation adaptation_for(const Adaptation& defaults, bool meta_trained,
                          const AdaptationOverrides& overrides);

}  // namespace pumeta
