// Whole-cloud upsampling with a trained backbone: the patch pipeline of reference §2, with
// optional test-time adaptation (paper Algorithm 2) before predicting.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <limits>
#include <string>

#include "pumeta/meta/maml.h"
#include "pumeta/models/backbone.h"

namespace pumeta {

struct UpsampleOptions {
    /// Output ratio; 0 = the model's. A power of the model's ratio (16 = 4 twice) applies the
    /// model repeatedly.
    int64_t ratio = 0;
    /// Patches per forward pass (bounds memory); 0 = the backbone's inference_batch_patches().
    int64_t batch_patches = 0;
    /// Each input point lies in about this many patches.
    double coverage = 3.0;
    /// Seed of the test-time downsampler (the only randomness of the pipeline).
    uint64_t seed = 0;
    /// Test-time adaptation steps N (0 = plain backbone).
    int64_t tta_steps = 0;
    /// "object": one adaptation on all patches of the input (a batch), θ' used for every
    /// patch, each patch's X↓ its own downsample; "patch": each patch adapts on its own;
    /// "cloud": one θ' from X↓ = the downsampled whole cloud, cut into network-sized patches
    /// paired with the points of X around them (docs/design.md). "oracle" is a diagnostic,
    /// never a result: θ' from N steps on the supervised pairs (X's patches, the ground truth
    /// around them), i.e. what N steps could gain with a perfect training signal; it needs
    /// tta_oracle_gt and a single pass (`pumeta eval --tta-unit oracle`, docs/design.md).
    std::string tta_unit = "object";
    /// The ground truth [M,3] in the input's frame, for tta_unit "oracle" only.
    at::Tensor tta_oracle_gt;
    /// X↓'s sampler for adaptation ("fps", "random", "nonuniform"); empty = the backbone's
    /// training-pair downsampler. E.g. "fps" makes X↓ of a blue-noise input blue-noise too.
    std::string tta_downsampler;
    /// Inner-loop settings (step size, which parameters adapt); inner_steps is ignored in
    /// favour of tta_steps.
    MetaOptions meta;
    /// Meta-SGD step sizes from a meta-trained checkpoint (empty: meta.inner_lr).
    StepSizes step_sizes;
    /// In object mode the inner loss of each step uses at most this many patches (a seeded
    /// minibatch), so adaptation cost stays bounded on huge inputs.
    int64_t tta_max_patches = 64;
    /// Farthest point sampling picks the final points when (candidates × output points) is at
    /// most this (its cost; 4e9 is about 6 s on one core); above it duplicates are first
    /// removed by patch ownership, which is linear. 2,048 -> 8,192 (2e8), 2,048 -> 16,384
    /// (8e8) and the second 4× pass of 16× (3.2e9) stay with FPS; 10k inputs at 4× (4.8e9)
    /// take the merge.
    double fps_budget = 4e9;
    /// A progress bar over the patch batches on a terminal (`pumeta upsample`; off inside
    /// `pumeta eval`, which has its own).
    bool show_progress = false;
};

struct UpsampleResult {
    at::Tensor points;  ///< float32 [ratio·N, 3], in the input's frame
    int64_t n_in = 0;
    int64_t patches = 0;     ///< patches upsampled (all passes)
    double seconds = 0;      ///< total wall time
    double tta_seconds = 0;  ///< of which adaptation
    /// The inner loss before and after adaptation: self-supervised L(F(X↓), X), or with
    /// tta_unit "oracle" the supervised loss on the ground truth (NaN without TTA).
    double loss_before = std::numeric_limits<double>::quiet_NaN();
    double loss_after = std::numeric_limits<double>::quiet_NaN();
};

/// Upsamples a cloud float32 [N,3] (N >= 1) to exactly ratio·N points. The model is never
/// modified. Same inputs and seed, same output.
UpsampleResult upsample_cloud(const Backbone& model, const at::Tensor& points,
                              const UpsampleOptions& options);

/// The non-learned baseline: each point plus the midpoints to its k nearest neighbours (k =
/// ratio by default), then exactly ratio·N of them: farthest point sampling while its cost
/// (candidates × output points) is within `fps_budget` (the network's, so every test set
/// keeps FPS), else weighted sample elimination with the Poisson-disk radius of ratio·N points
/// on the area the input covers, which is O(M log M).
at::Tensor midpoint_upsample(const at::Tensor& points, int64_t ratio, int64_t k = 0,
                             double fps_budget = UpsampleOptions().fps_budget);

}  // namespace pumeta
