// Model-agnostic meta-learning for upsampling (paper Sec. III, Algorithms 1 and 2), written
// only against the Backbone interface: no backbone-specific code here.
//
// Task n: a training pair (X_n, Y_n). Inner loop (adaptation): N steps of
//   θ_n ← θ_n − α ⊙ ∇ L(F_θn(X_n↓), X_n),   X_n↓ = backbone.downsample(X_n)
// Outer loss: mean_n L(F_θn(X_n), Y_n), differentiated w.r.t. the original θ (and α with
// Meta-SGD). Second-order by default: the inner gradients stay in the graph.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/models/backbone.h"
#include "pumeta/nn/parameters.h"

namespace pumeta {

/// The inner steps' optimiser: the paper's plain gradient steps θ ← θ − α ⊙ ∇L, or Adam
/// (learning rate α, fresh moments per adaptation), which only test-time adaptation offers.
enum class InnerOptimizer { kSgd, kAdam };
/// "sgd" or "adam"; InputError naming `context` otherwise.
InnerOptimizer parse_inner_optimizer(const std::string& name, const std::string& context);
std::string to_string(InnerOptimizer optimizer);

/// One run of the inner loop (adapt()): how many steps, how large, on which parameters.
struct InnerLoop {
    /// N: gradient steps.
    int64_t steps = 5;
    /// α for every adapting parameter without a per-tensor step size.
    double step_size = 1e-5;
    /// Name prefixes of the parameters that adapt (e.g. "upsample."); empty = all.
    std::vector<std::string> adapt{};
    /// FOMAML: with create_graph, the inner gradients are constants of the outer gradient.
    bool first_order = false;
    InnerOptimizer optimizer = InnerOptimizer::kSgd;

    /// Whether parameter `name` adapts.
    bool adapts(const std::string& name) const;
};

/// Meta-training's settings of the inner loop, stored in the JSON of every meta-trained model
/// (its defaults for test-time adaptation).
struct MetaOptions {
    /// N: inner gradient steps (paper: 5).
    int64_t inner_steps = 5;
    /// α: inner step size (paper: 1e-5 with PU-GCN's unscaled Chamfer loss — far too small
    /// to move the model; see docs/design.md). With plain SGD, scaling the inner loss by s is
    /// the same as scaling α by s.
    double inner_lr = 1e-5;
    /// FOMAML: inner gradients are treated as constants in the outer gradient.
    bool first_order = false;
    /// Meta-SGD with one learnable step size per parameter tensor (per layer, as MAML++'s
    /// learned per-layer rates), initialised to inner_lr; stored in the checkpoint's JSON.
    bool learn_inner_lr = false;
    /// Name prefixes of the parameters that adapt (e.g. "upsample."); empty = all.
    std::vector<std::string> adapt;

    /// Models meta-trained before these settings were reduced to the paper's also carry
    /// "outer_objective": "loss" and "inner_optimizer": "sgd", which are accepted; any other
    /// value of them is an InputError.
    static MetaOptions from_json(const nlohmann::json& j);
    /// InputError naming the field for a negative count or step size.
    void check() const;
    nlohmann::json to_json() const;
    /// The inner loop these settings describe (plain SGD steps).
    InnerLoop inner_loop() const;
};

/// Per-tensor inner step sizes (Meta-SGD): 0-dim tensors named like the parameters they
/// scale. An empty map means options.inner_lr for every adapting parameter.
using StepSizes = ParamMap;

/// Fresh Meta-SGD step sizes: inner_lr for every adapting parameter, leaves with
/// requires_grad.
StepSizes make_step_sizes(const Backbone& model, const MetaOptions& options);

/// Step sizes as JSON {name: value} for checkpoints, and back (as fixed, non-learning tensors).
nlohmann::json step_sizes_to_json(const StepSizes& sizes);
StepSizes step_sizes_from_json(const nlohmann::json& j);

/// The inner loop: returns θ' after loop.steps steps on the self-supervised loss
/// L(F_θ(x_down), x), with x_down float32 [B,n,3] and x [B,n·r,3] (a batch of pairs adapts one
/// θ'). Each adapting tensor steps by its entry of `step_sizes` (a 0-dim tensor) or else by
/// loop.step_size. With create_graph, θ' is a differentiable function of `params` (and of
/// `step_sizes`), for MAML's outer gradient; otherwise each step is detached (test-time
/// adaptation) and the returned tensors are leaves that share nothing with `params`' graph.
/// When `losses` is given it receives the inner loss before each step and after the last
/// (N + 1 values). InputError for Adam with create_graph or with per-tensor step sizes.
ParamMap adapt(const Backbone& model, const ParamMap& params, const at::Tensor& x_down,
               const at::Tensor& x, const InnerLoop& loop, const StepSizes& step_sizes,
               bool create_graph, std::vector<double>* losses = nullptr);

struct MetaStepResult {
    double outer_loss = 0;         ///< mean over tasks of L(F_θn(X_n), Y_n)
    double outer_loss_before = 0;  ///< mean over tasks of L(F_θ(X_n), Y_n) (no adaptation)
    double inner_loss_before = 0;  ///< mean self-supervised loss before the first inner step
    double inner_loss_after = 0;   ///< ... and after the last
    ParamMap grads;                ///< d outer / d θ, by name
    ParamMap step_size_grads;      ///< d outer / d α (Meta-SGD only)
    /// Tasks left out because their inner loop diverged; the means above are over the rest.
    int64_t dropped_tasks = 0;
    /// Tasks in the batch, dropped ones included.
    int64_t tasks = 0;
};

/// Data-parallel meta-training's collective, split so that it can be checked without
/// processes: pack_step_sum() turns one rank's result into sums over its kept tasks (and its
/// stop wish), the ranks' packets are summed element-wise, and unpack_step_sum() turns the sum
/// back into means over all ranks' kept tasks (dropped and task counts summed), i.e. what
/// meta_gradient() returns for the whole batch. Returns whether any rank wants to stop.
ParamMap pack_step_sum(const MetaStepResult& result, bool stop);
bool unpack_step_sum(const ParamMap& summed, MetaStepResult& result);

/// An inner loop diverged when a self-supervised loss is not finite or exceeds this factor
/// times the loss before adaptation (one PU-Dense task in about 60 went 0.135 -> 1,799 -> NaN
/// in two steps: on FPS-spread inputs whose 32 voxels are all out of each other's kernel
/// reach, every finest-level site holds the same features, and batch norm multiplies their
/// rounding differences by γ/√eps in each layer; docs/design.md).
constexpr double kDivergedInnerLoss = 10.0;

/// Whether an inner loop's losses (before, after step 1, …) diverged: one is not finite or
/// exceeds kDivergedInnerLoss times the first.
bool inner_loop_diverged(const std::vector<double>& losses);

/// One outer iteration's gradient over a batch of tasks x [B,N,3], y [B,rN,3], each task
/// adapted on its own (Algorithm 1, lines 3-8). Task n's X↓ uses seed + n. A task whose
/// inner loop diverges (kDivergedInnerLoss) is dropped with a warning rather than poisoning
/// the outer gradient with NaN.
MetaStepResult meta_gradient(const Backbone& model, const at::Tensor& x, const at::Tensor& y,
                             const MetaOptions& options, const StepSizes& step_sizes, uint64_t seed,
                             int64_t step = 0);

}  // namespace pumeta
