// The plug-in interface every upsampling network implements. Meta-learning (meta/) and
// training (train/) see backbones only through it.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "pumeta/nn/adam.h"
#include "pumeta/nn/parameters.h"

namespace pumeta {

/// A loss as named scalar terms, in the order they are summed.
using LossTerms = std::vector<std::pair<std::string, at::Tensor>>;

/// terms[0] + terms[1] + ... (in that order). `terms` must not be empty.
inline at::Tensor sum_of(const LossTerms& terms) {
    at::Tensor total = terms.front().second;
    for (size_t i = 1; i < terms.size(); ++i) total = total.add(terms[i].second);
    return total;
}

/// A point-cloud upsampling network whose forward pass can run from its own parameters or from
/// an explicit ParamMap with the same names (MAML's fast weights θ'), so that adapted weights
/// need no module copies and the inner loop stays twice differentiable. Every backbone passes
/// the conformance suite (tests/models/conformance.cpp; docs/design.md, "Backbones").
class Backbone {
  public:
    virtual ~Backbone() = default;

    /// Registry name ("pugcn", "dispu", "pudense").
    virtual std::string name() const = 0;
    /// Everything needed to rebuild this backbone with make_backbone(): {"backbone": name, ...}.
    virtual nlohmann::json config() const = 0;
    /// Upsampling ratio r.
    virtual int64_t ratio() const = 0;
    /// The config of this network at another ratio that the same weights serve (make_backbone
    /// of it + these parameters and buffers), or null when the weights are tied to their ratio
    /// (the default: PU-GCN's and Dis-PU's expansion layers are).
    virtual nlohmann::json config_for_ratio(int64_t ratio) const { return nullptr; }
    /// Points per input patch the network is trained on (256 for PU-GCN and Dis-PU).
    virtual int64_t patch_size() const = 0;
    /// Patches per forward pass that upsample fastest on a CPU when the caller does not say
    /// (UpsampleOptions::batch_patches = 0). Results do not depend on it.
    virtual int64_t inference_batch_patches() const { return 64; }
    /// Above 0, the pipeline runs the network on whole clouds (k-d tree parts of at most this
    /// many points) scaled to its patches' point spacing, instead of on patches, unless the
    /// caller says otherwise (UpsampleOptions::whole_cloud_points). Default 0: patches.
    virtual int64_t inference_whole_cloud_points() const { return 0; }

    /// Whether the backbone upsamples whole clouds by a pipeline of its own (cloud_candidates)
    /// instead of through patches of its input. Default false.
    virtual bool has_cloud_pipeline() const { return false; }
    /// That pipeline (Grad-PU's test: patches of the interpolated cloud, refined): candidates
    /// [M,3], M >= ratio·N, in the frame of `cloud` [N,3] (the input's unit sphere), from which
    /// the inference pipeline selects exactly ratio·N; with `params`; `seed` seeds whatever the
    /// pipeline draws (PU-Gaussian's samples). Only called when has_cloud_pipeline(). Default:
    /// undefined.
    virtual at::Tensor cloud_candidates(const at::Tensor& cloud, const ParamMap& params,
                                        uint64_t seed) const {
        return at::Tensor();
    }

    /// The backbone's own parameters (leaf tensors with requires_grad = true).
    ParamMap& parameters() { return params_; }
    const ParamMap& parameters() const { return params_; }

    /// Upsamples normalised patches: x float32 [B,N,3] -> [B,rN,3].
    virtual at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const = 0;
    at::Tensor upsample(const at::Tensor& x) const { return upsample(x, params_); }

    /// Training loss of upsampling `input` [B,N,3] towards `target` [B,rN,3] with `params`
    /// (a scalar, differentiable twice w.r.t. params). `step` is the training step for
    /// losses with schedules. Used by pretraining, by the MAML outer loss (X, Y) and by the
    /// inner / test-time loss (X↓, X).
    virtual at::Tensor loss(const at::Tensor& input, const at::Tensor& target,
                            const ParamMap& params, int64_t step = 0) const = 0;

    /// The same loss as named terms whose sum_of() is loss() (pretraining logs each term).
    /// Default: the one term "loss".
    virtual LossTerms loss_terms(const at::Tensor& input, const at::Tensor& target,
                                 const ParamMap& params, int64_t step = 0) const {
        return {{"loss", loss(input, target, params, step)}};
    }

    /// The training-pair downsampler: dense [B,M,3] -> sparse [B,M/r,3], the pattern the
    /// backbone was trained on (e.g. uniform random or FPS subset, or the PU-GAN non-uniform
    /// sampler). Builds X↓ from X for test-time adaptation.
    virtual at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const = 0;

    /// Non-trainable state saved with the model, e.g. batch-norm running statistics
    /// (empty for backbones without it). Never changed by loss() or upsample(), so
    /// meta-learning and test-time adaptation leave it untouched.
    ParamMap& buffers() { return buffers_; }
    const ParamMap& buffers() const { return buffers_; }

    /// Called by supervised pretraining once per step with the step's batch, before the
    /// loss, to update buffers (running statistics). Default: nothing.
    virtual void update_buffers(const at::Tensor& input, const ParamMap& params) {}

    /// Networks trained alongside the backbone with their own loss and optimiser (PU-GAN's
    /// discriminator): fresh parameters drawn from `seed`, or none (the default) for a
    /// backbone trained on its loss alone. Supervised training keeps them in the run state
    /// (resumable), never in the model file.
    virtual ParamMap make_auxiliary(uint64_t seed) const { return {}; }
    /// The supervised training loss with auxiliary networks: loss_terms plus the terms they
    /// contribute (e.g. the adversarial one), differentiable w.r.t. `params`. Default: the
    /// terms of loss_terms.
    virtual LossTerms training_terms(const at::Tensor& input, const at::Tensor& target,
                                     const ParamMap& params, const ParamMap& auxiliary,
                                     int64_t step) const {
        return loss_terms(input, target, params, step);
    }
    /// The auxiliary networks' own loss for a batch (e.g. the discriminator's on `target`
    /// against the backbone's output from `input`), differentiable w.r.t. `auxiliary` only;
    /// minimised by their own Adam after each step of the backbone.
    virtual at::Tensor auxiliary_loss(const at::Tensor& input, const at::Tensor& target,
                                      const ParamMap& params, const ParamMap& auxiliary,
                                      int64_t step) const {
        return at::Tensor();
    }
    /// The learning rate of the auxiliary networks' Adam at `step`, before the run schedule's
    /// decay (the trainer multiplies it by the schedule's rate over its initial one, so that
    /// both optimisers decay together, as PU-GAN's).
    virtual double auxiliary_lr(int64_t step) const { return 1e-4; }

    /// How supervised training's Adam treats parameter `name` (the original's optimiser
    /// groups): its learning rate is the schedule's times lr_scale, and weight_decay (L2 on the
    /// gradient, as torch.optim.Adam) is added. Default: one group, no decay.
    virtual OptimizerGroup optimizer_group(const std::string& name) const { return {}; }
    /// Supervised training's learning rate at `step` is the schedule's times this (a
    /// curriculum's phases). Default: 1.
    virtual double learning_rate_factor(int64_t step) const { return 1.0; }

    /// The edge of the grid the outputs lie on, in the patch frame (voxel centres; 0, the
    /// default: continuous outputs). `pumeta eval --method grid-floor` measures what such a
    /// grid costs on whole objects.
    virtual double output_grid() const { return 0; }

    /// Where the backbone's error on patches comes from, in its own terms (`pumeta diagnose`):
    /// for input [B,N,3] and target [B,rN,3], named numbers per patch ({"name": [B values]}),
    /// each the mean over the patch where it is a distance. Null (the default): none.
    virtual nlohmann::json diagnose(const at::Tensor& input, const at::Tensor& target) const {
        return nullptr;
    }

    /// Moves parameters and buffers to a device ("cpu", "cuda").
    void to(const std::string& device);

  protected:
    ParamMap params_;
    ParamMap buffers_;
};

/// Builds a backbone from its JSON config (config["backbone"] picks the kind); InputError for
/// an unknown kind or invalid fields. Parameters are freshly initialised from config["seed"].
std::unique_ptr<Backbone> make_backbone(const nlohmann::json& config);

/// `model` rebuilt at `ratio` (make_backbone of Backbone::config_for_ratio) holding the very
/// same parameter and buffer tensors, so that gradients and in-place updates of either reach
/// both; null when its weights do not serve `ratio`. The sharing ends when to() moves either
/// model to another device (new tensors): move `model` first, then share.
std::unique_ptr<Backbone> share_weights_at(const Backbone& model, int64_t ratio);

using BackboneFactory = std::function<std::unique_ptr<Backbone>(const nlohmann::json&)>;

/// Adds a backbone kind to the registry (called once per backbone in registry.cpp).
/// `small_config` is the kind's smallest useful config ({"backbone": name, ...}; a model that
/// builds and runs in milliseconds on one core), kept for the backbone conformance suite
/// (tests/models/conformance.cpp runs every registered kind through the Backbone contract
/// with it) and for quick experiments; null for none, which that suite reports as a failure.
/// InternalError for a name registered twice or a small config of another kind.
void register_backbone(const std::string& name, BackboneFactory factory,
                       nlohmann::json small_config = nullptr);

/// Names of the registered backbone kinds, sorted.
std::vector<std::string> registered_backbones();

/// The small config registered with kind `name` (null when it has none); InputError for an
/// unknown kind.
nlohmann::json small_backbone_config(const std::string& name);

}  // namespace pumeta
