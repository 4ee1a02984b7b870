// Meta-training (paper Algorithm 1) from a pretrained checkpoint, resumable: a RunStage of the
// shared run loop (train/run_loop.h: the run directory's files, resume, Ctrl-C); best.pt is
// the model with the lowest validation CD after adaptation. Saved models carry the meta
// options (and learned step sizes) in their JSON, so `pumeta upsample` adapts with them.
//
// Data-parallel over W processes (config.distributed): every rank takes B/W tasks of each
// outer batch and the outer gradients are averaged before the optimiser step, which gives
// the update of one process with all B tasks (up to float summation order). Rank 0 alone
// writes the run directory; every rank resumes from it.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pumeta/meta/maml.h"
#include "pumeta/train/run_settings.h"

namespace pumeta {

/// Run settings (train/run_settings.h; 1,000 steps, logs every 5, validation every 50,
/// checkpoints every 25 by default) plus meta-training's own.
struct MetaTrainConfig : RunSettings {
    MetaTrainConfig() {
        steps = 1000;
        log_every = 5;
        val_every = 50;
        checkpoint_every = 25;
    }

    std::string init;  ///< pretrained checkpoint θ0
    MetaOptions meta;
    /// B: tasks per outer iteration (paper 8).
    int64_t tasks_per_batch = 8;
    /// Outer Adam: lr · decay^(step / decay_steps) (paper: Adam 1e-4, decay 0.99; JSON fields
    /// outer_lr, outer_lr_decay, outer_lr_decay_steps).
    LrSchedule outer{1e-4, 0.99, 100};
    /// Adam learning rate of Meta-SGD step sizes (relative to inner_lr's scale).
    double step_size_lr = 1e-3;
    int64_t val_tasks = 64;
    /// Ratios of the tasks, for a model whose one set of weights serves several
    /// (Backbone::config_for_ratio: Meta-PU, MPU). Empty: every task at the model's ratio, X
    /// from the loader. Else each outer step draws one ratio R from the list (a hash of seed and
    /// step) and every task of the step is X = the model's downsampler at R applied to the GT
    /// patch, X↓ the same applied to X; validation task i is at ratio task_ratios[i % size].
    /// The weights are shared: one θ, adapted and meta-trained at every listed ratio.
    std::vector<int64_t> task_ratios;

    static MetaTrainConfig from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

/// Validation of adaptation on fixed held-out tasks.
struct AdaptationScore {
    double cd_before = 0;          ///< CD of F_θ(X) vs Y
    double cd_after = 0;           ///< CD of F_θ'(X) vs Y after N inner steps
    double inner_loss_before = 0;  ///< self-supervised loss before adaptation
    double inner_loss_after = 0;   ///< ... and after
};

struct MetaTrainResult {
    int64_t steps = 0;
    AdaptationScore last;
    double best_cd_after = 0;
};

/// Meta-trains (or, with resume, continues the run in config.run_dir) until config.steps;
/// stops early, after writing a checkpoint, as train() does.
MetaTrainResult meta_train(const MetaTrainConfig& config, bool resume,
                           double stop_after_seconds = 0,
                           const std::vector<std::string>& allow_changes = {});

}  // namespace pumeta
