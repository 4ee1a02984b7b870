// PU-Dense (Akhtar et al., IEEE TIP 2022): a sparse voxel U-Net of Inception and Pyramid
// blocks whose last generative transposed convolution proposes new voxels; an occupancy logit
// per proposed voxel, trained with BCE against the ground truth's voxels, and the top rN
// voxels as the output. Built on the twice-differentiable engine of nn/sparse, so MAML can
// adapt it. 13,172,441 parameters at the paper width with last kernel 5.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/models/backbone.h"
#include "pumeta/nn/sparse/sparse_batch_norm.h"
#include "pumeta/nn/sparse/sparse_tensor.h"

namespace pumeta {

/// PU-Dense's configuration: the JSON fields of {"backbone": "pudense", ...}. Every field is
/// optional; unknown fields are rejected.
struct PuDenseOptions {
    /// Upsampling ratio r >= 1 (the output keeps the rN most likely voxels).
    int64_t ratio = 8;
    /// "paper" (channels 32, 32, 64, 128, 256) or "compact" (16, 16, 32, 64, 64; 1.6 M
    /// parameters, for 2 CPU cores). Sets `channels` unless the config gives them.
    std::string preset = "paper";
    /// Channels of the five levels (tensor strides 1, 2, 4, 8, 16): multiples of 4 with
    /// channels[0] == channels[1] (the decoder adds the stride-1 encoder features).
    std::vector<int64_t> channels = {32, 32, 64, 128, 256};
    /// Odd kernel size >= 3 of the generative transposed convolution: new voxels lie within
    /// (K-1)/2 voxels of the stride-2 sites.
    int64_t last_kernel_size = 5;
    /// Voxels per unit length of the input frame (normalised patches have radius 1): voxel
    /// edge h = 1 / resolution. About one voxel per ground-truth point spacing: on the x4
    /// training patches (1,024 GT points, mean spacing 0.053) 86 % of GT points get a voxel of
    /// their own at 17; 24 is the same for x8.
    double resolution = 24.0;
    /// Points per input patch of the patch pipeline.
    int64_t patch_size = 256;
    /// Training-pair / X↓ downsampler (PU-Dense: a uniform random subset).
    std::string downsampler = "random";
    /// Factor on the BCE loss (meta-learning rates depend on the loss scale).
    double loss_scale = 1.0;
    /// Weight of a new batch in the running statistics (PyTorch's BatchNorm momentum).
    double bn_momentum = 0.1;
    /// Normalise with each input's own statistics in upsample() too (as meta-training's outer
    /// loss does) instead of the running statistics.
    bool batch_stats_at_inference = false;
    /// Sub-voxel refinement (pumeta's extension, off in the original; docs/design.md,
    /// "PU-Dense"): a two-layer per-voxel head on the last features moves each selected voxel
    /// centre by an offset of at most refine_range voxel edges per axis, trained with
    /// refine_weight · CD(moved points, target) added to the BCE. Its last layer starts at
    /// zero, so a refined model initialised from a faithful one starts at its outputs.
    bool refine = false;
    double refine_weight = 1000.0;
    double refine_range = 1.0;
    /// Seed of the parameter initialisation.
    uint64_t seed = 0;

    /// InputError "pudense config: ..." for unknown fields, wrong types or invalid values.
    static PuDenseOptions from_json(const nlohmann::json& config);
    /// Every field, with "backbone": "pudense".
    nlohmann::json to_json() const;
};

/// The network's output: one occupancy logit per generated stride-1 site.
struct Occupancy {
    CoordinateSetPtr sites;  ///< the generated voxels, batch column = batch element
    at::Tensor logits;       ///< [G]
    /// [G,3]: the refinement's offsets in the input frame (PuDenseOptions::refine), else
    /// undefined.
    at::Tensor offsets;
};

class PuDense : public Backbone {
  public:
    explicit PuDense(const PuDenseOptions& options);

    std::string name() const override { return "pudense"; }
    nlohmann::json config() const override { return options_.to_json(); }
    int64_t ratio() const override { return options_.ratio; }
    /// Any ratio: the output keeps the r·N most likely voxels. The patch size becomes
    /// patch_size·ratio()/r so that each patch still yields as many points (and voxels) as
    /// the model was trained to produce (docs/design.md).
    nlohmann::json config_for_ratio(int64_t ratio) const override;
    int64_t patch_size() const override { return options_.patch_size; }
    /// Small batches: a batch's generated voxels and kernel maps grow with it and first-touch
    /// page clearing dominates. One 2,048 -> 16,384 object, compact, one thread: 9.5 s with
    /// 64 patches per pass (2.1 GB peak RSS), 5.2 s with 8, 4.2 s with 2 (0.46 GB).
    int64_t inference_batch_patches() const override { return 2; }
    /// Whole clouds, as the original upsamples (k-d tree parts of at most 8,192 points): on
    /// `val` at 8× the compact model's CD is 45 % lower than on patches (docs/design.md).
    int64_t inference_whole_cloud_points() const override { return 8192; }
    const PuDenseOptions& options() const { return options_; }
    /// Voxel edge length h in the input frame.
    double voxel_size() const { return 1.0 / options_.resolution; }
    /// The voxel edge; 0 (continuous outputs) with the sub-voxel refinement.
    double output_grid() const override { return options_.refine ? 0.0 : voxel_size(); }

    /// The network on occupied voxels (stride-1 sites, feature 1 each).
    Occupancy occupancy(const CoordinateSetPtr& voxels, const ParamMap& params,
                        const BatchNormContext& norm) const;

    /// x [B,N,3] -> [B,rN,3]: the centres of each element's rN most likely voxels (running
    /// statistics unless batch_stats_at_inference), moved by their offsets with the
    /// refinement. When fewer voxels are generated than rN, the ranked ones repeat
    /// cyclically, so the count is always exact.
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override;
    using Backbone::upsample;

    /// loss_scale · BCE-with-logits between the occupancy of every generated voxel and its
    /// membership in target's voxels, averaged over the generated voxels of the batch; with
    /// the refinement plus refine_weight · CD between the moved centres of the M most likely
    /// voxels (M = target points, as upsample() selects) and the target. Batch statistics;
    /// `step` unused. Twice differentiable in params.
    at::Tensor loss(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                    int64_t step = 0) const override;
    /// "bce" and, with the refinement, "refine_cd" (weighted).
    LossTerms loss_terms(const at::Tensor& input, const at::Tensor& target, const ParamMap& params,
                         int64_t step = 0) const override;

    /// downsample_points(dense, M / r, options().downsampler, seed).
    at::Tensor downsample(const at::Tensor& dense, uint64_t seed) const override;

    /// Moves the running statistics of every batch norm towards this batch's.
    void update_buffers(const at::Tensor& input, const ParamMap& params) override;

    /// The voxel decomposition of the CD (docs/design.md, "PU-Dense"), per patch:
    /// - floor_cd: CD of the ideal output, the target's own voxels (most occupied first,
    ///   repeated cyclically to rN as upsample() does) against the target: what voxel centres
    ///   cannot go below;
    /// - candidates_cd: the same ideal restricted to the voxels the network generates (the
    ///   target's voxels among them, then the network's ranking for the rest);
    /// - candidate_recall: the share of the target's voxels among the generated ones;
    /// - precision: the share of the selected voxels that are target voxels.
    nlohmann::json diagnose(const at::Tensor& input, const at::Tensor& target) const override;

    /// The occupied voxels of x [B,N,3]. The last few results are cached (keyed by content), so
    /// the kernel maps built for an input are reused by repeated calls on it: the inner loop,
    /// update_buffers then loss.
    CoordinateSetPtr voxels(const at::Tensor& x) const;

  private:
    void check_input(const at::Tensor& x, const ParamMap& params, const char* what) const;
    /// Per batch element, the rows of occ's sites it outputs: its `wanted` most likely voxels
    /// by logit, repeated cyclically when it has fewer.
    std::vector<at::Tensor> selected(const Occupancy& occ, int64_t batch, int64_t wanted) const;
    /// The selected voxels' centres (moved by occ.offsets when defined): [batch, wanted, 3].
    at::Tensor output_points(const Occupancy& occ, int64_t batch, int64_t wanted) const;

    PuDenseOptions options_;

    struct CachedVoxels {
        at::Tensor points;
        CoordinateSetPtr voxels;
    };
    mutable std::mutex cache_mutex_;
    mutable std::deque<CachedVoxels> cache_;
};

/// The registry's factory: PuDense(PuDenseOptions::from_json(config)).
std::unique_ptr<Backbone> make_pudense(const nlohmann::json& config);

/// PU-Dense's smallest useful config (channels 4-8, 16 voxels per unit length, 64-point
/// patches, x4), registered with the kind for the backbone conformance suite and quick
/// experiments (register_backbone). Not smaller patches: the coarsest level of a 32-point
/// patch has 2-3 sites, whose batch norm makes the meta-objective too rough for finite
/// differences.
nlohmann::json pudense_small_config();

}  // namespace pumeta
