// Dis-PU (Li et al., "Point Cloud Upsampling via Disentangled Refinement", CVPR 2021): a dense
// EdgeConv feature extractor, duplicate-up with a 2-D grid code and a coarse regressor (the
// "dense generator"), then a spatial refiner (local, skip and non-local branches) whose
// bounded offsets move the coarse points. Layer shapes follow the official TensorFlow code
// (DisPU/generator.py, Common/ops.py); 1,046,966 parameters at the paper's width.
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/models/backbone.h"

namespace pumeta {

/// Dis-PU's configuration: the JSON fields of {"backbone": "dispu", ...}. "preset" ("paper",
/// the default, or "compact") sets every width first; fields given explicitly override it.
/// Unknown fields are rejected.
struct DisPuOptions {
    /// Width preset the fields below started from: "paper" or "compact".
    std::string preset = "paper";
    /// Upsampling ratio r >= 1.
    int64_t ratio = 4;
    /// Neighbours of every EdgeConv graph and refiner group, and the width of the refiner's
    /// weight net (its k×k mixing); small inputs use min(k, points available). >= 1.
    int64_t k = 16;
    /// Growth rate of the dense EdgeConv blocks (also the first layer's width; the 1×1
    /// compression before blocks 2.. has 2·growth channels). Features: 5·growth·blocks.
    int64_t growth = 24;
    /// Dense EdgeConv blocks (>= 1).
    int64_t blocks = 4;
    /// Duplicate-up: widths of its two convolutions (the second is the per-point feature
    /// width of the upsampled points).
    int64_t expand_channels = 256;
    int64_t feature_channels = 128;
    /// Coordinate regressors (coarse and fine): hidden widths.
    int64_t regressor_channels = 256;
    int64_t regressor_bottleneck = 64;
    /// Refiner: width of the local branch's shared MLPs, output width of every branch.
    int64_t refiner_channels = 128;
    int64_t refiner_out_channels = 256;
    /// Non-local attention bottleneck (the original: max(32, feature_channels / 2)).
    int64_t attention_channels = 64;
    /// Points per training patch.
    int64_t patch_size = 256;
    /// Training-pair / X↓ downsampler: fps, random or nonuniform (PU-GAN's, which Dis-PU's
    /// data pipeline uses).
    std::string downsampler = "nonuniform";
    /// Weight of the repulsion loss on the fine points (Dis-PU: 1).
    double repulsion_weight = 1.0;
    /// Add each input point to the coarse regressor's output for its r copies (coarse =
    /// x + regress(...)), as PU-GCN does, instead of the original's absolute coordinates.
    /// Off by default (the original); the 2-core presets turn it on (docs/design.md).
    bool coarse_residual = false;
    /// Training steps per epoch of the fine-loss schedule (see dispu_fine_weight). Default:
    /// the original's epoch, 24,000 PU-GAN patches in batches of 28.
    int64_t steps_per_epoch = 857;
    /// Seed of the parameter initialisation.
    uint64_t seed = 0;

    /// InputError "dispu config: ..." for unknown fields, wrong types or invalid values.
    static DisPuOptions from_json(const nlohmann::json& config);
    /// Every field, with "backbone": "dispu".
    nlohmann::json to_json() const;
};

/// Which statistics the weight net's batch norm uses.
enum class NormStatistics {
    kBatch,    ///< the batch's own (training, meta-learning inner and outer loss)
    kRunning,  ///< the running averages in buffers() (inference)
};

/// Both outputs of Dis-PU, float [B,rN,3]; the r copies of input point i are rows s·N + i.
struct DisPuOutput {
    at::Tensor coarse;
    at::Tensor fine;  ///< coarse + an offset in [−0.5, 0.5]³
};

class DisPu : public Backbone {
  public:
    explicit DisPu(const DisPuOptions& options);

    std::string name() const override { return "dispu"; }
    nlohmann::json config() const override { return options_.to_json(); }
    int64_t ratio() const override { return options_.ratio; }
    int64_t patch_size() const override { return options_.patch_size; }
    const DisPuOptions& options() const { return options_; }

    /// x float [B,N,3] (N >= 2) -> coarse and fine points. Memory: the non-local attention
    /// scores are computed in blocks of at most 2^24 (see blocked_attention).
    DisPuOutput forward(const at::Tensor& x, const ParamMap& params,
                        NormStatistics statistics) const;

    /// The fine output of forward() with running statistics.
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override;
    using Backbone::upsample;

    /// Dis-PU's loss with batch statistics (buffers are untouched):
    ///   1000·CD(coarse, target) + w · 1000·CD(fine, target) + repulsion_weight · rep(fine)
    /// with Dis-PU's CD = mean fwd + mean bwd squared distance (2 · chamfer_loss) and
    /// w = dispu_fine_weight(max(step, pretrain_steps() − 1), steps_per_epoch): the schedule
    /// continues from where pretraining left it, so meta-learning (which passes its own step
    /// or 0) sees the weight the model was last trained with, as the original's epoch counter
    /// stored in its checkpoints.
    at::Tensor loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                    int64_t step = 0) const override;
    /// "coarse", "fine" (weighted by the schedule) and, with a repulsion weight, "repulsion".
    LossTerms loss_terms(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                         int64_t step = 0) const override;

    /// downsample_points(dense, M / r, options().downsampler, seed).
    at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const override;

    /// Pretraining only: moves the weight net's running statistics towards this batch's
    /// (momentum 0.05, TensorFlow's decay 0.95) and counts the step in pretrain_steps().
    void update_buffers(const at::Tensor& input, const ParamMap& params) override;

    /// Number of update_buffers() calls (pretraining steps) this model has seen.
    int64_t pretrain_steps() const;

  private:
    struct Coarse {
        at::Tensor features;  ///< [B,rN,feature_channels]
        at::Tensor points;    ///< [B,rN,3]
    };
    Coarse generate(const at::Tensor& x, const ParamMap& params) const;
    at::Tensor extract_features(const at::Tensor& x, const ParamMap& params) const;
    at::Tensor duplicate_up(const at::Tensor& features, const ParamMap& params) const;
    at::Tensor refine(const Coarse& coarse, const ParamMap& params,
                      NormStatistics statistics) const;
    void check_input(const at::Tensor& x, const ParamMap& params, const char* what) const;

    DisPuOptions options_;
};

/// Dis-PU's weight of the fine Chamfer term: 0.01, 0.1, 0.5, 1.0 as
/// tf.train.piecewise_constant(epoch, [10, 20, 30], ...) on the completed-epoch counter
/// epoch = step / steps_per_epoch (so 0.01 while epoch <= 10, 1.0 from epoch 31).
double dispu_fine_weight(int64_t step, int64_t steps_per_epoch);

/// Duplicate-up's grid code: float32 [r,2]. r = nx·ny with nx the largest divisor of r not
/// above floor(sqrt(r)) + 1; row j·nx + i = (x_i, y_j), x and y evenly spaced in [−0.2, 0.2]
/// (a single value is −0.2), as the original's gen_grid.
at::Tensor dispu_grid(int64_t ratio);

/// The registry's factory: DisPu(DisPuOptions::from_json(config)).
std::unique_ptr<Backbone> make_dispu(const nlohmann::json& config);

/// Dis-PU's smallest useful config (widths 4-8, 2 blocks, k 4 on 16-point patches, x4),
/// registered with the kind for the backbone conformance suite and quick experiments
/// (register_backbone).
nlohmann::json dispu_small_config();

}  // namespace pumeta
