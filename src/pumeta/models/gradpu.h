// Grad-PU (He et al., CVPR 2023): upsampling as gradient descent on a learned point-to-point
// distance. A dense Point3DConv feature extractor reads a midpoint-interpolated patch once; a
// regressor predicts, for any query, its distance to the true surface from the query, the
// 3-NN interpolation of four local feature maps and a global one; the interpolated points
// then descend that distance. As the official PyTorch code (yunhe20/Grad-PU @ 435b6a07,
// models/ and test.py): 67,073 parameters with the defaults, any ratio from one set of
// weights (config_for_ratio), 16x as 4x twice.
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/models/backbone.h"
#include "pumeta/nn/batch_norm.h"

namespace pumeta {

/// Grad-PU's configuration: the JSON fields of {"backbone": "gradpu", ...}; every field is
/// optional and defaults to the original's PU-GAN setting. Unknown fields are rejected.
struct GradPuOptions {
    /// Upsampling ratio r >= 2 (the weights serve every ratio).
    int64_t ratio = 4;
    /// Neighbours of the Point3DConv graph, the point itself included (>= 2).
    int64_t k = 16;
    /// Dense blocks, dense layers per block, feature width, growth per layer.
    int64_t blocks = 3;
    int64_t layers = 3;
    int64_t channels = 32;
    int64_t growth = 32;
    /// Points per training patch (the sparse input; its interpolation has r times as many).
    int64_t patch_size = 256;
    /// Points per refinement patch of the interpolated cloud (the original: 4 · 256).
    int64_t refine_patch_size = 1024;
    /// Refinement patches per refine_patch_size interpolated points (the original: 3).
    int64_t patch_rate = 3;
    /// Descent steps on the predicted distance, its step and cap (the original's test: 10
    /// steps of 50 on the PU-GAN weights, 500 on the PU1K weights, distances clamped at 0.2).
    int64_t steps = 10;
    double step_size = 50;
    double max_distance = 0.2;
    /// "cloud_mean" (the original's): each step descends the mean predicted distance over
    /// every point of every patch of the cloud, so a point moves by step_size over the number
    /// of those points times its gradient, less as the input grows; "per_point": by step_size
    /// times its own gradient, whatever the input's size.
    std::string step_rule = "cloud_mean";
    /// Training: queries are the interpolated points plus N(0, query_sigma²) noise.
    double query_sigma = 0.02;
    /// Training-pair / X↓ downsampler (the original draws PU-GAN's non-uniform subsets).
    std::string downsampler = "nonuniform";
    /// Seed of the parameter initialisation and of the training queries' noise.
    uint64_t seed = 0;

    /// InputError "gradpu config: ..." for unknown fields, wrong types or invalid values.
    static GradPuOptions from_json(const nlohmann::json& config);
    /// Every field, with "backbone": "gradpu".
    nlohmann::json to_json() const;
};

class GradPu : public Backbone {
  public:
    explicit GradPu(const GradPuOptions& options);

    std::string name() const override { return "gradpu"; }
    nlohmann::json config() const override { return options_.to_json(); }
    int64_t ratio() const override { return options_.ratio; }
    /// Every ratio from 2 to 64: the weights do not depend on it.
    nlohmann::json config_for_ratio(int64_t ratio) const override;
    int64_t patch_size() const override { return options_.patch_size; }
    const GradPuOptions& options() const { return options_; }

    /// Each patch of x float [B,N,3] as a cloud of its own (midpoint interpolation, one
    /// refinement patch of all r·N points when it holds at most refine_patch_size, the steps
    /// with running statistics) -> [B,rN,3].
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override;
    using Backbone::upsample;

    /// The original's test pipeline on a whole cloud float [N,3] (Backbone::cloud_candidates):
    /// normalised to the unit sphere, interpolated to r·N midpoints, cut into
    /// int(r·N / refine_patch_size · patch_rate) patches of the refine_patch_size nearest
    /// interpolated points around FPS seeds, each normalised, refined, restored: every refined
    /// point of every patch, [P·refine_patch_size, 3], for the final selection. Deterministic:
    /// `seed` is not used.
    at::Tensor cloud_candidates(const at::Tensor& cloud, const ParamMap& params,
                                uint64_t seed) const override;
    bool has_cloud_pipeline() const override { return true; }

    /// The original's training loss: L1 between the predicted and the true distance (to the
    /// nearest point of `target`) at the interpolated points of `input` jittered by
    /// query_sigma, summed over points, mean over patches; batch norm on batch statistics
    /// (train mode), also in the inner loop of meta-learning and adaptation. The jitter is
    /// drawn from (seed, step).
    at::Tensor loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                    int64_t step = 0) const override;

    /// downsample_points(dense, M / r, options().downsampler, seed).
    at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const override;

    /// Running statistics of every batch norm from the features of the batch's interpolated
    /// patches (momentum 0.1, PyTorch's).
    void update_buffers(const at::Tensor& input, const ParamMap& params) override;

    /// The predicted distance of queries q [B,Q,3] to the surface of interpolated patches
    /// p [B,M,3] (both in the patch frame) -> [B,Q], with running or batch statistics.
    at::Tensor distance(const at::Tensor& p, const at::Tensor& q, const ParamMap& params,
                        bool batch_statistics = false) const;

  private:
    struct Features;
    Features extract(const at::Tensor& p, const ParamMap& params, bool batch_statistics,
                     BatchMomentsMap* statistics = nullptr) const;
    at::Tensor regress(const Features& features, const at::Tensor& q, const ParamMap& params) const;
    /// Patches p [B,M,3] after the descent steps, each point moving by `point_step` times the
    /// gradient of its clamped predicted distance.
    at::Tensor refine(const at::Tensor& p, const ParamMap& params, double point_step) const;

    GradPuOptions options_;
};

/// Midpoint interpolation of patches x [B,N,3] -> [B, ratio·N, 3]: the midpoints from each
/// point to its min(2·ratio, N) nearest, the point itself included (so the points
/// themselves), then FPS from the first; the original's models/utils.py.
at::Tensor midpoint_interpolate(const at::Tensor& x, int64_t ratio);

/// The registry's factory: GradPu(GradPuOptions::from_json(config)).
std::unique_ptr<Backbone> make_gradpu(const nlohmann::json& config);

/// Grad-PU's smallest useful config (width 4, one block of two layers, k 4, 16-point
/// patches, three descent steps of 0.05 per point, about the original's 50 / 1,024),
/// registered for the backbone conformance suite.
nlohmann::json gradpu_small_config();

}  // namespace pumeta
