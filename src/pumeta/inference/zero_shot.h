// Zero-shot internal learning in the spirit of ZSPU (Zhou et al., 2022): a backbone trained
// from scratch at test time on the input's own pairs (X↓, X) only, then used to upsample X
// through the usual patch pipeline. It is a baseline: the gap between it and the pretrained
// backbone is what external pretraining buys, and the gap to "ours" what meta-training adds.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>

#include "pumeta/models/backbone.h"

namespace pumeta {

struct ZeroShotOptions {
    /// Adam steps on the input's own patches (the test-time budget).
    int64_t steps = 300;
    /// Patches of X per step (drawn at random, with replacement across steps).
    int64_t batch_patches = 8;
    double lr = 1e-3;
    /// A random rotation of each patch in every step (the only augmentation).
    bool augment = true;
    /// Seeds the fresh initialisation, the patch draws and the downsampler.
    uint64_t seed = 0;
};

struct ZeroShotResult {
    std::unique_ptr<Backbone> model;
    /// Mean self-supervised loss L(F(X↓), X) over the first and the last ten steps.
    double loss_first = 0;
    double loss_last = 0;
    double seconds = 0;
};

/// Trains a fresh backbone built from `architecture` (make_backbone; its "seed" is replaced
/// by options.seed, no pretrained weights are used) on cloud float32 [N,3]: patches of
/// architecture's patch size are the targets X, their downsampling by the backbone's ratio
/// the inputs X↓.
ZeroShotResult train_zero_shot(const nlohmann::json& architecture, const at::Tensor& cloud,
                               const ZeroShotOptions& options);

}  // namespace pumeta
