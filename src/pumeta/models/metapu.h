// Meta-PU (Ye et al., "Meta-PU: An Arbitrary-Scale Upsampling Network for Point Cloud", TVCG
// 2021): a point head, two residual-graph-convolution (RGC) up-sampling stages whose first
// block takes its two 128×128 weights from small networks of the scale ("scale-conditioned
// weights"), four candidate offsets per point and farthest point sampling to exactly ⌊N·R⌋
// points. One set of weights serves every ratio 2..16. Layer shapes follow the official
// PyTorch code (model/networks.py, GenModel); 3,021,440 parameters at the paper's width.
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/models/backbone.h"

namespace pumeta {

/// Meta-PU's configuration: the JSON fields of {"backbone": "metapu", ...}; every field is
/// optional and defaults to the paper's setting. Unknown fields are rejected.
struct MetaPuOptions {
    /// The ratio upsample() produces, 2 <= ratio <= candidates² (config_for_ratio gives the
    /// others; the weights are the same). 16: the ratio of the x16 training patch sets.
    int64_t ratio = 16;
    /// Feature width of every RGC block (the generated matrices are channels × channels).
    int64_t channels = 128;
    /// RGC blocks after the scale-conditioned block of stage 1 and of stage 2.
    int64_t stage1_blocks = 9;
    int64_t stage2_blocks = 10;
    /// Neighbours of every graph (the point head, both stages, the feature transfer); small
    /// inputs use as many as exist.
    int64_t k = 8;
    /// Hidden width of each scale-conditioned weight generator (fc11 1→h, fc12 h→C²).
    int64_t generator_hidden = 32;
    /// Candidate points per point in each stage; the largest ratio is candidates².
    int64_t candidates = 4;
    /// Input points per patch at `ratio` (config_for_ratio keeps patch_size·ratio, about the
    /// 4,096-point ground-truth patches of training).
    int64_t patch_size = 256;
    /// The reconstruction term: "sinkhorn" (the original's) or "chamfer" (chamfer_loss, PU-GCN's
    /// CD: a fraction of the Sinkhorn's cost per step on CPU; docs/design.md, "Meta-PU").
    std::string reconstruction = "sinkhorn";
    /// Sinkhorn divergence: blur (ε = blur²), reach (ρ = reach²), ε-scaling factor, and how
    /// it is differentiated: "envelope" or "unrolled" (nn/sinkhorn_loss.h).
    double blur = 1e-3;
    double reach = 0.2;
    double sinkhorn_scaling = 0.5;
    std::string sinkhorn_gradient = "envelope";
    /// Weights of the loss terms: Σ ½‖W‖² of the generated matrices, the uniformity loss
    /// (metapu_uniform_options) and PU-Net's repulsion loss (punet_repulsion_loss).
    double scale_weights_penalty = 1e-3;
    double uniform_weight = 1e-3;
    double repulsion_weight = 5e-3;
    /// Supervised training's optimiser groups, as the original's: the weight generators
    /// (fc11, fc12, fcskip) at generator_lr_scale times the schedule's learning rate (its 1e-3
    /// against 1e-4 for the convolutions), and weight decay on every tensor.
    double generator_lr_scale = 10.0;
    double weight_decay = 1e-5;
    /// Seed of the parameter initialisation.
    uint64_t seed = 0;

    /// InputError "metapu config: ..." for unknown fields, wrong types or invalid values.
    static MetaPuOptions from_json(const nlohmann::json& config);
    /// Every field, with "backbone": "metapu".
    nlohmann::json to_json() const;
};

/// One forward pass: the output points and the penalty Σ ½‖W‖²_F over the four generated
/// matrices (a scalar, differentiable w.r.t. the generators).
struct MetaPuOutput {
    at::Tensor points;  ///< [B,n_out,3]
    at::Tensor scale_weights_norm;
};

/// The scale code a generator sees for a stage's scale s (s² a ratio): √R_q / candidates with
/// R_q the nearest entry to s² of the grid 1.1, 1.2, ..., candidates² (rounded index; the
/// original truncates, which maps 4 to 3.9).
double metapu_scale_code(double stage_scale, int64_t candidates);

/// The training scale of step `step`: one of 1.1, 1.2, ..., max_ratio, drawn uniformly by a
/// hash of the step (the same for every batch element, as the original draws one per batch).
double metapu_training_scale(int64_t step, int64_t max_ratio);

/// Whether parameter `name` belongs to a scale-conditioned weight generator (fc11, fc12,
/// fcskip): the original's "fc" optimiser group.
bool metapu_generator_parameter(const std::string& name);

/// Meta-PU's input sampler (its data loader): m of the M points of each element of dense
/// [B,M,3], PU-GAN's non-uniform sampler on the points sorted by distance to a random one
/// when m <= M/2, else all points but such a sample of M − m (kept in index order).
at::Tensor metapu_sparse_input(const at::Tensor& dense, int64_t m, uint64_t seed);

class MetaPu : public Backbone {
  public:
    explicit MetaPu(const MetaPuOptions& options);

    std::string name() const override { return "metapu"; }
    nlohmann::json config() const override { return options_.to_json(); }
    int64_t ratio() const override { return options_.ratio; }
    /// Any integer ratio 2..candidates² (InputError outside): the same weights, patch_size
    /// scaled so that each patch still yields patch_size·ratio() points.
    nlohmann::json config_for_ratio(int64_t ratio) const override;
    int64_t patch_size() const override { return options_.patch_size; }
    /// 4,096 output points of 23 RGC blocks per patch: a few patches per pass.
    int64_t inference_batch_patches() const override { return 8; }
    const MetaPuOptions& options() const { return options_; }

    /// x [B,N,3] (N >= 2) upsampled by `scale` (1 < scale <= candidates²) to n_out points
    /// (stage 1: ⌊N·round(√scale, 3)⌋ points; stage 2: n_out <= candidates × those).
    MetaPuOutput forward(const at::Tensor& x, const ParamMap& params, double scale,
                         int64_t n_out) const;

    /// forward(x, params, ratio(), ratio()·N).points.
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override;
    using Backbone::upsample;

    /// The loss of upsampling `input` [B,N,3] to `target` [B,M,3] at scale M/N (InputError
    /// unless 1 < M/N <= candidates²); `step` unused. Terms: "sinkhorn" (or "chamfer"),
    /// "scale_weights", "uniform", "repulsion" (those with a weight).
    at::Tensor loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                    int64_t step = 0) const override;
    LossTerms loss_terms(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                         int64_t step = 0) const override;

    /// Supervised training over the original's range of scales: `input` is ignored; the
    /// step's scale R (metapu_training_scale) gives ⌊M/R⌋ input points drawn from `target`
    /// [B,M,3] by metapu_sparse_input and the ground truth its first ⌊⌊M/R⌋·R⌋ points.
    LossTerms training_terms(const at::Tensor& input, const at::Tensor& target,
                             const ParamMap& params, const ParamMap& auxiliary,
                             int64_t step) const override;

    /// metapu_sparse_input(dense, M / ratio(), seed).
    at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const override;
    /// The weight generators at generator_lr_scale, every tensor with weight_decay.
    OptimizerGroup optimizer_group(const std::string& name) const override;

  private:
    struct Stage {
        at::Tensor points;
        at::Tensor features;
        at::Tensor scale_weights_norm;
    };
    Stage stage(const std::string& prefix, int64_t blocks, bool offsets_after_blocks,
                const at::Tensor& xyz, const at::Tensor& features, double scale, int64_t n_out,
                const ParamMap& params) const;
    at::Tensor point_head(const at::Tensor& x, const ParamMap& params) const;

    MetaPuOptions options_;
};

/// The registry's factory: MetaPu(MetaPuOptions::from_json(config)).
std::unique_ptr<Backbone> make_metapu(const nlohmann::json& config);

/// Meta-PU's smallest useful config (width 4, one block per stage, k 4 on 16-point patches,
/// x4, unrolled Sinkhorn derivatives), registered with the kind for the backbone conformance
/// suite and quick experiments (register_backbone).
nlohmann::json metapu_small_config();

}  // namespace pumeta
