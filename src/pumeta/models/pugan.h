// PU-GAN (Li et al., "PU-GAN: a Point Cloud Upsampling Adversarial Network", ICCV 2019): a
// dense EdgeConv feature extractor, an up-down-up expansion unit with self-attention and 2-D
// grid codes that generates r' = r + 2 points per input point, a coordinate regressor, and
// farthest point sampling from r'N down to rN; trained against a discriminator with LSGAN
// losses. Layer shapes follow the official TensorFlow code (Upsampling/generator.py,
// Upsampling/discriminator.py, Common/ops.py): 541,601 generator and 142,594 discriminator
// parameters at the paper's width and r = 4.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/models/backbone.h"

namespace pumeta {

/// PU-GAN's configuration: the JSON fields of {"backbone": "pugan", ...}. "preset" ("paper",
/// the default, or "compact") sets every width first; fields given explicitly override it.
/// Unknown fields are rejected.
struct PuGanOptions {
    /// Width preset the fields below started from: "paper" or "compact".
    std::string preset = "paper";
    /// Upsampling ratio r >= 1.
    int64_t ratio = 4;
    /// Extra copies generated before farthest point sampling: r' = r + extra_copies points
    /// per input point (the original's more_up, 2). The weights depend on r'.
    int64_t extra_copies = 2;
    /// Neighbours of every dynamic EdgeConv graph (min(k, N − 1) on small inputs).
    int64_t k = 16;
    /// Dense EdgeConv widths (nn/dense_edge_conv.h): first layer, growth, blocks.
    int64_t first = 24;
    int64_t growth = 24;
    int64_t blocks = 4;
    /// Per-point feature width of the expansion unit (conv0 and the up and down blocks'
    /// outputs). The attention's query and key width is (feature_channels + 2) / 4.
    int64_t feature_channels = 128;
    /// Hidden widths of the up block (after the attention) and of the down block.
    int64_t up_channels = 256;
    int64_t down_channels = 256;
    /// Hidden width of the coordinate regressor (fc_layer1).
    int64_t head_channels = 64;
    /// The discriminator's first width s (the original's start_number 32): convolutions
    /// 3 → s → 2s, attention on 4s, 4s → 4s → 8s, then fully connected 8s → 8s → 1.
    int64_t discriminator_channels = 32;
    /// Points per training patch.
    int64_t patch_size = 256;
    /// Training-pair / X↓ downsampler: fps, random or nonuniform (the original's training
    /// input, the default).
    std::string downsampler = "nonuniform";
    /// Loss weights: EMD, uniformity, repulsion (loss()), the L2 regulariser on the generator
    /// and the adversarial term (pretraining only, training_terms()).
    double emd_weight = 100.0;
    double uniform_weight = 10.0;
    double repulsion_weight = 1.0;
    double regularization = 1e-5;
    double adversarial_weight = 0.5;
    /// The discriminator's Adam learning rate (constant).
    double discriminator_lr = 1e-4;
    /// The EMD's matching: "auction" (default; see nn/emd_loss.h) or "approximate" (Fan et
    /// al.'s, the original's).
    std::string emd_matching = "auction";
    /// Seed of the parameter initialisation (the discriminator's comes from the run's seed).
    uint64_t seed = 0;

    /// r + extra_copies.
    int64_t copies() const { return ratio + extra_copies; }

    /// InputError "pugan config: ..." for unknown fields, wrong types or invalid values.
    static PuGanOptions from_json(const nlohmann::json& config);
    /// Every field, with "backbone": "pugan".
    nlohmann::json to_json() const;
};

class PuGan : public Backbone {
  public:
    explicit PuGan(const PuGanOptions& options);

    std::string name() const override { return "pugan"; }
    nlohmann::json config() const override { return options_.to_json(); }
    int64_t ratio() const override { return options_.ratio; }
    int64_t patch_size() const override { return options_.patch_size; }
    const PuGanOptions& options() const { return options_; }

    /// The generator before its last step: x float [B,N,3] (N >= 2) -> the r'N regressed
    /// points [B,r'N,3], copy c of point n at row c·N + n. Coordinates are absolute (no
    /// residual to x). Memory: the self-attention over all r'N points is computed in blocks
    /// of at most 2^24 scores without gradients (see blocked_attention).
    at::Tensor generate(const at::Tensor& x, const ParamMap& params) const;

    /// generate() reduced to rN points by farthest point sampling from row 0 of each patch:
    /// [B,N,3] -> [B,rN,3].
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override;
    using Backbone::upsample;

    /// The reconstruction loss, sum_of(loss_terms()); `step` is unused.
    at::Tensor loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                    int64_t step = 0) const override;
    /// For pred = upsample(input): "emd" emd_weight · EMD(pred, target) (equal point counts),
    /// "uniform" uniform_weight · uniform_loss(pred) (PU-GAN's settings) and "repulsion"
    /// repulsion_weight · repulsion_loss(pred) (4 neighbours, h = 0.001). No adversarial
    /// term: meta-learning and test-time adaptation have no discriminator.
    LossTerms loss_terms(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                         int64_t step = 0) const override;

    /// downsample_points(dense, M / r, options().downsampler, seed).
    at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const override;

    /// The discriminator's parameters ("d.*"), Xavier-uniform from `seed`; none when
    /// adversarial_weight is 0.
    ParamMap make_auxiliary(uint64_t seed) const override;
    /// loss_terms, then "regularization" (regularization · ½‖w‖² over every generator weight
    /// and bias except the last layer's, not the attention scales γ) and, unless
    /// adversarial_weight is 0, "adversarial" (adversarial_weight · mean_b (D(pred) − 1)²).
    LossTerms training_terms(const at::Tensor& input, const at::Tensor& target,
                             const ParamMap& params, const ParamMap& auxiliary,
                             int64_t step) const override;
    /// The LSGAN discriminator loss mean_b (D(target) − 1)² + mean_b D(upsample(input))², the
    /// generated points without gradient. The trainer calls it after training_terms on the
    /// same batch: the generator's output from its first call there is reused (the
    /// discriminator sees the output from before the generator's updates on the batch, one
    /// or several, as in the original, where its step comes first), so the step pays for no
    /// generator pass; another input is upsampled afresh.
    at::Tensor auxiliary_loss(const at::Tensor& input, const at::Tensor& target,
                              const ParamMap& params, const ParamMap& auxiliary,
                              int64_t step) const override;
    double auxiliary_lr(int64_t step) const override { return options_.discriminator_lr; }

  private:
    LossTerms reconstruction_terms(const at::Tensor& pred, const at::Tensor& target) const;
    at::Tensor expand(const at::Tensor& features, const ParamMap& params,
                      const std::string& prefix) const;
    at::Tensor contract(const at::Tensor& features, const ParamMap& params,
                        const std::string& prefix) const;
    void check_input(const at::Tensor& x, const ParamMap& params, const char* what) const;

    PuGanOptions options_;
    /// training_terms' input and its output without gradient, for auxiliary_loss.
    mutable std::mutex last_mutex_;
    mutable at::Tensor last_input_, last_output_;
};

/// The discriminator's score per cloud: cloud [B,M,3] -> [B] (linear, no sigmoid), with the
/// parameters of PuGan::make_auxiliary.
at::Tensor pugan_discriminate(const at::Tensor& cloud, const ParamMap& discriminator);

/// The up block's input: features [B,N,C] tiled r' times in copy-major order (row c·N + n
/// holds point n, copy c) with copy c's 2-D grid code appended -> [B,r'N,C+2]. The grid is
/// the original's gen_grid (dispu_grid): r' = nx·ny, nx the largest divisor of r' not above
/// ⌊√r'⌋ + 1, code of copy c = (x_{c mod nx}, y_{⌊c/nx⌋}) on even steps in [−0.2, 0.2].
at::Tensor pugan_tile_with_grid(const at::Tensor& features, int64_t copies);

/// The registry's factory: PuGan(PuGanOptions::from_json(config)).
std::unique_ptr<Backbone> make_pugan(const nlohmann::json& config);

/// PU-GAN's smallest useful config (widths 4-8, 2 blocks, k 4 on 16-point patches, x4),
/// registered with the kind for the backbone conformance suite and quick experiments.
nlohmann::json pugan_small_config();

}  // namespace pumeta
