// Supervised pretraining (paper Eq. 1): min_θ L(F_θ(X), Y) over training patches, resumable:
// a RunStage of the shared run loop (train/run_loop.h: the run directory's files, resume,
// Ctrl-C); best.pt is the model with the lowest validation CD.
//
// Data-parallel over W processes (config.distributed): every rank takes batch_size/W patches
// of each batch and the gradients are averaged before the Adam step, which equals one process
// with the whole batch up to float summation order for backbones without batch norm (with
// it, each rank normalises by its own shard's statistics, as DDP without SyncBatchNorm;
// running statistics are averaged over the ranks). Rank 0 alone writes the run directory.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/train/run_settings.h"

namespace pumeta {

/// Run settings (train/run_settings.h; steps default to 10,000) plus supervised training's own.
struct TrainConfig : RunSettings {
    TrainConfig() { steps = 10000; }

    /// Backbone config for make_backbone() (ignored on resume: the state's config is used).
    nlohmann::json backbone;
    int64_t batch_size = 64;
    /// Adam's learning rate: max(lr_min, lr · lr_decay_rate^(step / lr_decay_steps)), PU-GCN's
    /// schedule (JSON fields lr, lr_decay_rate, lr_decay_steps, lr_min).
    LrSchedule schedule{1e-3, 0.7, 50000, 1e-6};
    /// Adam steps of the backbone on each batch, every one on the same patches, before the
    /// auxiliary networks' step (PU-GAN's original: two generator steps per discriminator step).
    /// Buffers update once per batch; the logged loss (and each term) is the mean over the
    /// updates, the later ones measured after the earlier ones' steps.
    int64_t updates_per_batch = 1;
    /// Validation patches (fixed: the first val_patches of a seeded draw, no augmentation).
    int64_t val_patches = 256;
    /// Optional checkpoint whose parameters and buffers initialise a fresh run wherever name
    /// and shape match (e.g. an 8x model warm-started from a 4x one: only the ratio-dependent
    /// upsampling layers keep their random initialisation). Ignored on resume.
    std::string init_from;

    /// Fields not given keep their defaults; unknown fields are an InputError.
    static TrainConfig from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

struct TrainResult {
    int64_t steps = 0;
    double best_val_cd = 0;
    double last_val_cd = 0;
};

/// Trains (or, with resume, continues the run in config.run_dir) until config.steps.
/// Stops early, after writing a checkpoint, when `stop_after_seconds` > 0 elapses.
TrainResult train(const TrainConfig& config, bool resume, double stop_after_seconds = 0,
                  const std::vector<std::string>& allow_changes = {});

}  // namespace pumeta
