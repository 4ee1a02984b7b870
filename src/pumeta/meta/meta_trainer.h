// Meta-training (paper Algorithm 1) from a pretrained checkpoint, resumable. The run
// directory has the same layout as pretraining's (train/trainer.h): state.ckpt, model.pt,
// best.pt (lowest validation CD after adaptation) and log.jsonl. Saved models carry the
// meta options (and learned step sizes) in their JSON, so `pumeta upsample` adapts with them.
//
// Data-parallel over W processes (config.distributed): every rank takes B/W tasks of each
// outer batch and the outer gradients are averaged before the optimiser step, which gives
// the update of one process with all B tasks (up to float summation order). Rank 0 alone
// writes the run directory; every rank resumes from it.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "pumeta/distributed/process_group.h"
#include "pumeta/meta/maml.h"

namespace pumeta {

struct MetaTrainConfig {
    std::string init;  ///< pretrained checkpoint θ0
    std::string train_data;
    std::string val_data;
    std::string run_dir;
    MetaOptions meta;
    /// B: tasks per outer iteration (paper 8).
    int64_t tasks_per_batch = 8;
    int64_t steps = 1000;
    /// Outer Adam: lr · decay^(step / decay_steps) (paper: Adam 1e-4, decay 0.99).
    double outer_lr = 1e-4;
    double outer_lr_decay = 0.99;
    int64_t outer_lr_decay_steps = 100;
    /// Adam learning rate of Meta-SGD step sizes (relative to inner_lr's scale).
    double step_size_lr = 1e-3;
    std::string sampler = "fps";
    bool augment = true;
    int64_t log_every = 5;
    int64_t val_every = 50;
    int64_t val_tasks = 64;
    int64_t checkpoint_every = 25;
    uint64_t seed = 1;
    /// Processes and rendezvous; tasks_per_batch must be a multiple of the world size.
    DistributedConfig distributed;

    static MetaTrainConfig from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

/// Validation of adaptation on fixed held-out tasks.
struct AdaptationScore {
    double cd_before = 0;          ///< CD of F_θ(X) vs Y
    double cd_after = 0;           ///< CD of F_θ'(X) vs Y after N inner steps
    double inner_loss_before = 0;  ///< self-supervised loss before adaptation
    double inner_loss_after = 0;   ///< ... and after
    /// Mean first_step_alignment() of the tasks: does the first inner step point downhill
    /// on X → Y?
    double alignment = 0;
    /// The same with the next task's supervised pair in place of X → Y: the share of the
    /// alignment that any input's self-supervised step would give.
    double alignment_other = 0;
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
