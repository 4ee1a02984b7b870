// PU-Gaussian (arXiv 2509.20207): each input point of a patch predicts an anisotropic Gaussian
// (offset, scale, rotation) from point-transformer features; a few points drawn from each
// Gaussian make a coarse dense patch, which a refinement network (a point transformer and a
// ratio-1 up unit, applied twice with the same weights at test time) moves onto the surface.
// As the official PyTorch code computes it (mvg-inatech/PU-Gaussian @ 19d00c80: model/ and
// test.py): 268,109 parameters that affect the output, any ratio up to the draws per point,
// 16x as 4x twice. The multi-view rendering the original computes and discards, its unused
// feature projection and its confidence head are left out.
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/models/backbone.h"

namespace pumeta {

/// PU-Gaussian's configuration: the JSON fields of {"backbone": "pugaussian", ...}; every field
/// is optional and defaults to the original's PU-GAN setting. Unknown fields are rejected.
struct PuGaussianOptions {
    /// Upsampling ratio r, 2 <= r <= samples (the weights serve every such ratio).
    int64_t ratio = 4;
    /// Points drawn from each Gaussian (the coarse patch has samples · N points).
    int64_t samples = 6;
    /// Neighbours of both point transformers, the point itself included.
    int64_t k = 16;
    /// Widths: the Gaussian module's features and attention, the refinement's features and
    /// attention, the hidden layer of both position encodings.
    int64_t gaussian_channels = 64;
    int64_t gaussian_attention = 32;
    int64_t refine_channels = 128;
    int64_t refine_attention = 64;
    int64_t position_channels = 64;
    /// Refinement passes at test time (the original: 2; training runs one, as the original's).
    int64_t refine_passes = 2;
    /// Draws of the standard normal beyond this magnitude are drawn again.
    double truncation = 2.0;
    /// Points per patch, and patches per patch_size input points of the original's test.
    int64_t patch_size = 256;
    int64_t patch_rate = 3;
    /// Training-pair / X↓ downsampler (PU-GAN's non-uniform subsets, as Grad-PU's).
    std::string downsampler = "nonuniform";
    /// Seed of the parameter initialisation and of the draws (mixed with each patch's points).
    uint64_t seed = 0;

    /// InputError "pugaussian config: ..." for unknown fields, wrong types or invalid values.
    static PuGaussianOptions from_json(const nlohmann::json& config);
    /// Every field, with "backbone": "pugaussian".
    nlohmann::json to_json() const;
};

class PuGaussian : public Backbone {
  public:
    explicit PuGaussian(const PuGaussianOptions& options);

    std::string name() const override { return "pugaussian"; }
    nlohmann::json config() const override { return options_.to_json(); }
    int64_t ratio() const override { return options_.ratio; }
    /// Every ratio from 2 to `samples` (one pass); powers of the ratio run as repeated passes.
    nlohmann::json config_for_ratio(int64_t ratio) const override;
    int64_t patch_size() const override { return options_.patch_size; }
    const PuGaussianOptions& options() const { return options_; }

    /// Each patch of x float [B,N,3], normalised to its unit sphere, through the network and
    /// FPS to r·N -> [B,rN,3]. The draws of patch b come from the model's seed and that patch's
    /// points, so a patch's output does not depend on its batch.
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override;
    using Backbone::upsample;

    /// The original's test on a whole cloud float [N,3] in its unit sphere: int(N / patch_size
    /// · patch_rate) patches of the patch_size nearest points around FPS seeds, each normalised,
    /// upsampled and reduced to r·patch_size points by FPS, restored and merged:
    /// [P·r·patch_size, 3]. Draws from `seed` and each patch's points.
    at::Tensor cloud_candidates(const at::Tensor& cloud, const ParamMap& params,
                                uint64_t seed) const override;
    bool has_cloud_pipeline() const override { return true; }

    /// Chamfer distance (squared, nn/chamfer_loss.h) of the coarse draws and of one refinement
    /// of them to the target, summed (the original's training: one refinement pass, both
    /// terms); batch norm on batch statistics. Draws from (seed, step).
    at::Tensor loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                    int64_t step = 0) const override;
    LossTerms loss_terms(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                         int64_t step = 0) const override;

    /// downsample_points(dense, M / r, options().downsampler, seed).
    at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const override;

    /// Running statistics of the four batch norms from the batch's training forward pass
    /// (momentum 0.1, PyTorch's).
    void update_buffers(const at::Tensor& input, const ParamMap& params) override;

    /// The stages of one patch batch, for tests: the Gaussians of x [B,N,3] (means [B,N,3],
    /// covariances [B,N,3,3], features [B,N,C]), the coarse draws [B,S·N,3] for the standard
    /// normal draws `epsilon` [B,N,S,3], and `passes` refinements of them.
    struct Stages {
        at::Tensor means, covariances, features, coarse, refined;
    };
    Stages forward(const at::Tensor& x, const at::Tensor& epsilon, const ParamMap& params,
                   int64_t passes, bool batch_statistics) const;

    /// Truncated standard normal draws [B,N,samples,3] for patches x [B,N,3] (dtype of x): each
    /// patch's from a generator seeded by `seed` and its coordinates' bytes.
    at::Tensor draw_epsilon(const at::Tensor& x, uint64_t seed) const;

  private:
    /// forward() that also keeps the input of every batch norm in `statistics` (update_buffers).
    Stages forward_collecting(const at::Tensor& x, const at::Tensor& epsilon,
                              const ParamMap& params, int64_t passes, bool batch_statistics,
                              ParamMap* statistics) const;
    /// What the refinement's inference path computes once per patch batch: mlp2's first layer
    /// split by its input's parts (the Gaussian features' product already repeated per draw),
    /// the up unit's conv1 and shortcut stacked with the transposed convolution folded in.
    struct RefineProducts {
        at::Tensor own, drawn, global, up, up_bias;
    };
    RefineProducts refine_products(const at::Tensor& features, const ParamMap& params) const;
    /// upsample() with the draws seeded from `seed`.
    at::Tensor upsample_seeded(const at::Tensor& x, const ParamMap& params, uint64_t seed) const;

    PuGaussianOptions options_;
};

/// The registry's factory: PuGaussian(PuGaussianOptions::from_json(config)).
std::unique_ptr<Backbone> make_pugaussian(const nlohmann::json& config);

/// PU-Gaussian's smallest useful config (widths 4 to 8, k 4, 16-point patches), registered
/// for the backbone conformance suite.
nlohmann::json pugaussian_small_config();

}  // namespace pumeta
