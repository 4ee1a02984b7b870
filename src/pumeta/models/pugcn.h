// PU-GCN (Qian et al., CVPR 2021): Inception DenseGCN feature extractor + NodeShuffle
// upsampler, as in the official TensorFlow code. 75,971 parameters at r = 4 with defaults.
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/models/backbone.h"

namespace pumeta {

/// PU-GCN's configuration: the JSON fields of {"backbone": "pugcn", ...}; every field is
/// optional and defaults to the paper's setting. Unknown fields are rejected.
struct PuGcnOptions {
    /// Upsampling ratio r >= 1.
    int64_t ratio = 4;
    /// Width of the head, of each Inception path and of DenseGCN's growth (>= 1).
    int64_t channels = 32;
    /// Inception DenseGCN blocks (>= 1).
    int64_t blocks = 2;
    /// Neighbours per edge convolution (>= 1).
    int64_t k = 20;
    /// Dilation of the second Inception path: every d-th of the k·d nearest (>= 1).
    int64_t dilation = 2;
    /// Channels per generated point in NodeShuffle (>= 1).
    int64_t upsample_channels = 64;
    /// Hidden width of the coordinate reconstruction (>= 1).
    int64_t reconstruction_channels = 32;
    /// Points per training patch.
    int64_t patch_size = 256;
    /// Training-pair / X↓ downsampler: fps, random or nonuniform (see downsample_points).
    std::string downsampler = "fps";
    /// Factor on the Chamfer loss (meta-learning rates depend on the loss scale).
    double loss_scale = 1.0;
    /// Seed of the parameter initialisation.
    uint64_t seed = 0;

    /// InputError "pugcn config: ..." for unknown fields, wrong types or invalid values.
    static PuGcnOptions from_json(const nlohmann::json& config);
    /// Every field, with "backbone": "pugcn".
    nlohmann::json to_json() const;
};

class PuGcn : public Backbone {
  public:
    explicit PuGcn(const PuGcnOptions& options);

    std::string name() const override { return "pugcn"; }
    nlohmann::json config() const override { return options_.to_json(); }
    int64_t ratio() const override { return options_.ratio; }
    int64_t patch_size() const override { return options_.patch_size; }
    const PuGcnOptions& options() const { return options_; }

    /// x float [B,N,3] (N >= 2; k shrinks to N-1 on small patches) -> [B,rN,3]; point i's r
    /// outputs are consecutive.
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override;
    using Backbone::upsample;

    /// loss_scale · Chamfer(upsample(input), target) (see chamfer_loss); `step` is unused.
    at::Tensor loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                    int64_t step = 0) const override;

    /// downsample_points(dense, M / r, options().downsampler, seed).
    at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const override;

  private:
    PuGcnOptions options_;
};

/// The registry's factory: PuGcn(PuGcnOptions::from_json(config)).
std::unique_ptr<Backbone> make_pugcn(const nlohmann::json& config);

/// PU-GCN's smallest useful config (width 4, k 4 on 16-point patches, x4), registered with
/// the kind for the backbone conformance suite and quick experiments (register_backbone).
nlohmann::json pugcn_small_config();

}  // namespace pumeta
