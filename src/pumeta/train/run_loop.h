// The loop every training run shares: supervised pretraining (train/trainer.cpp) and MAML
// meta-training (meta/meta_trainer.cpp) differ only in their RunStage (the step, the
// validation, the optimiser state); the loop owns what must behave the same in both: step
// cadence, log.jsonl, validation and best.pt, state.ckpt and model.pt, the time limit, Ctrl-C,
// the ranks' agreement, and the save of a run stopped before its first step.
//
// A run directory holds:
//   state.ckpt   latest model + optimiser state + counters (what --resume continues)
//   model.pt     latest model (a plain checkpoint usable by `pumeta upsample`)
//   best.pt      the model with the lowest validation score so far
//   log.jsonl    one JSON object per logged step and per validation
#pragma once

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "pumeta/data/patch_set.h"
#include "pumeta/distributed/process_group.h"
#include "pumeta/models/backbone.h"
#include "pumeta/nn/parameters.h"
#include "pumeta/train/run_settings.h"
#include "pumeta/train/validation.h"

namespace pumeta {

/// What one optimisation step reports to the loop.
struct StepOutcome {
    /// The step's training objective; a non-finite value ends the run with an InternalError.
    double loss = 0;
    /// Whether any rank wants to stop after this step (combined in the step's collective, so
    /// that every rank stops at the same step).
    bool stop = false;
    /// The progress bar's status text.
    std::string progress;
};

/// What one validation reports.
struct ValidationOutcome {
    /// Lower is better: best.pt holds the model with the lowest score.
    double score = 0;
    /// Fields of the validation's log.jsonl record ("step", "best", "seconds" and "cpu_seconds"
    /// are added).
    nlohmann::json fields = nlohmann::json::object();
    /// A one-line summary for the log.
    std::string summary;
};

/// One kind of training run, driven by run_loop(). A stage restores its own optimiser and data
/// position from the resumed state when it is built; the loop restores the step and the best
/// score.
class RunStage {
  public:
    virtual ~RunStage() = default;

    /// One optimisation step of the model; `step` steps are done before it. `wants_stop` says
    /// whether this process wants to stop (time limit, Ctrl-C); the stage asks it once its
    /// gradients are computed and combines the answer over the ranks with them.
    virtual StepOutcome step(int64_t step, const std::function<bool()>& wants_stop) = 0;

    /// The fields of the training log record for the steps since the last one (the loop adds
    /// "step", "seconds", "steps_per_second" and "cpu_seconds": the run's CPU time over all its
    /// resumes).
    virtual nlohmann::json log_fields() = 0;

    /// Whether the run has validation data.
    virtual bool validates() const = 0;
    /// Scores the model on the validation data (a collective when distributed).
    virtual ValidationOutcome validate(int64_t step) = 0;

    /// The optimiser tensors and the counters (beyond the step and the best score) that
    /// --resume needs, added to `tensors` and `info`.
    virtual void save_state(ParamMap& tensors, nlohmann::json& info) const = 0;

    /// The JSON stored with model.pt and best.pt after `step` steps.
    virtual nlohmann::json model_extra(int64_t step) const = 0;
};

struct RunLoopOptions {
    /// Names the run in log lines ("train", "meta-train").
    std::string what;
    std::string run_dir;
    int64_t steps = 0;
    int64_t log_every = 20;
    int64_t val_every = 500;
    int64_t checkpoint_every = 500;
    /// Every this many steps the ranks check that their parameters are identical (0: never).
    int64_t check_every = 0;
    /// Validate a fresh run before its first step (meta-training: the pretrained model's
    /// score, which adaptation must beat).
    bool validate_first = false;
    /// The best score's key in the state's info ("best_val_cd", "best_cd_after").
    std::string best_key;
    /// The run's comparable_config(), stored in the state and compared on resume.
    nlohmann::json config;
    /// Stop (after the step that passes it, with a checkpoint) after this many seconds; 0: no
    /// limit.
    double stop_after_seconds = 0;
};

struct RunLoopResult {
    int64_t steps = 0;
    double best_score = 0;
    double last_score = 0;
};

/// Runs `stage` on `model` from the step in `resumed_info` (null for a fresh run) until
/// options.steps, a time limit or Ctrl-C; only the main rank writes the run directory, and
/// every rank returns once its last checkpoint is on disk.
RunLoopResult run_loop(Backbone& model, RunStage& stage, const RunLoopOptions& options,
                       ProcessGroup& group, const nlohmann::json& resumed_info);

/// The loop's options from a run's settings; `config` is the run's full config (stored as
/// comparable_config()). best_key and validate_first are the caller's.
RunLoopOptions loop_options(const RunSettings& settings, const std::string& what,
                            const nlohmann::json& config, double stop_after_seconds);

/// What a run reads: its training patches, a loader over this rank's shard of every batch of
/// `batch` patches, and the first `val_count` patches of the validation set (when val_data is
/// given).
class RunData {
  public:
    /// InputError when a patch set's ratio is not the model's.
    RunData(const RunSettings& settings, int64_t batch, int64_t val_count, const Backbone& model,
            const ProcessGroup& group);
    RunData(const RunData&) = delete;
    RunData& operator=(const RunData&) = delete;

    const PatchSet train_set;
    PatchLoader loader;  ///< over train_set (declared after it)
    std::optional<ValidationSet> val;
};

/// Copies the model's parameters, buffers and `extra` tensors of rank 0 to every rank and
/// checks that all resume at the same `counters` (start_in_sync with the model included).
void start_ranks_in_sync(ProcessGroup& group, Backbone& model, const nlohmann::json& counters,
                         ParamMap extra);

}  // namespace pumeta
