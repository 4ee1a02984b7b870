#include "pumeta/train/run_loop.h"

#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>

#include "pumeta/core/error.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/core/progress.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/train/training_state.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

/// The run directory's files and the best-score bookkeeping of one run_loop() call.
class RunFiles {
  public:
    RunFiles(Backbone& model, RunStage& stage, const RunLoopOptions& options, bool writes)
        : model_(model), stage_(stage), options_(options), writes_(writes) {}

    void save_state(int64_t step, double best, double cpu_seconds) const {
        if (!writes_) return;
        ParamMap tensors;
        nlohmann::json info = {
            {"step", step}, {options_.best_key, best}, {"cpu_seconds", cpu_seconds}};
        stage_.save_state(tensors, info);
        info[kRunConfigKey] = options_.config;
        save_training_state(path("state.ckpt"), model_, tensors, info);
        save_checkpoint(path("model.pt"), model_, stage_.model_extra(step));
    }

    void save_best(int64_t step) const {
        if (writes_) save_checkpoint(path("best.pt"), model_, stage_.model_extra(step));
    }

    void log(const nlohmann::json& record) const {
        if (writes_) append_log(path("log.jsonl"), record);
    }

  private:
    std::string path(const char* name) const {
        return (fs::path(options_.run_dir) / name).string();
    }

    Backbone& model_;
    RunStage& stage_;
    const RunLoopOptions& options_;
    bool writes_;
};

LoaderOptions loader_options(const RunSettings& settings, int64_t batch,
                             const ProcessGroup& group) {
    LoaderOptions loader;
    loader.batch_size = batch;
    loader.sampler = parse_input_sampler(settings.sampler);
    loader.augment = settings.augment;
    loader.seed = settings.seed;
    loader.shard_index = group.rank();
    loader.shard_count = group.world_size();
    return loader;
}

/// CPU time (user + system, every thread) this process has used so far.
double process_cpu_seconds() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    auto seconds = [](const timeval& t) { return t.tv_sec + t.tv_usec * 1e-6; };
    return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

}  // namespace

RunData::RunData(const RunSettings& settings, int64_t batch, int64_t val_count,
                 const Backbone& model, const ProcessGroup& group)
    : train_set(
          load_patch_set_for_ratio(settings.train_data, model.ratio(), hdf5_patch_keys(settings))),
      loader(train_set, loader_options(settings, batch, group)) {
    if (!settings.val_data.empty())
        val = make_validation_set(
            load_patch_set_for_ratio(settings.val_data, model.ratio(), hdf5_patch_keys(settings)),
            val_count, parse_input_sampler(settings.sampler), settings.seed);
}

RunLoopOptions loop_options(const RunSettings& settings, const std::string& what,
                            const nlohmann::json& config, double stop_after_seconds) {
    RunLoopOptions loop;
    loop.what = what;
    loop.run_dir = settings.run_dir;
    loop.steps = settings.steps;
    loop.log_every = settings.log_every;
    loop.val_every = settings.val_every;
    loop.checkpoint_every = settings.checkpoint_every;
    loop.check_every = settings.distributed.check_every;
    loop.config = comparable_config(config);
    loop.stop_after_seconds = stop_after_seconds;
    return loop;
}

void start_ranks_in_sync(ProcessGroup& group, Backbone& model, const nlohmann::json& counters,
                         ParamMap extra) {
    for (auto& [name, p] : model.parameters()) extra["theta/" + name] = p;
    for (auto& [name, b] : model.buffers()) extra["buffer/" + name] = b;
    start_in_sync(group, counters, extra);
}

RunLoopResult run_loop(Backbone& model, RunStage& stage, const RunLoopOptions& options,
                       ProcessGroup& group, const nlohmann::json& resumed_info) {
    const bool writes = group.is_main();
    const RunFiles files(model, stage, options, writes);
    int64_t step = 0;
    double best = std::numeric_limits<double>::infinity();
    double last = best;
    if (!resumed_info.is_null()) {
        step = resumed_info.at("step");
        // A run without validation stores its initial infinity, which JSON writes as null.
        if (resumed_info.value(options.best_key, nlohmann::json()).is_number())
            best = resumed_info[options.best_key];
    }

    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    // Core-seconds of the whole run, carried across resumes: what "trained for N core-hours"
    // is measured by (the wall clock depends on what else shares the machine).
    const double cpu_before = resumed_info.is_null() ? 0.0 : resumed_info.value("cpu_seconds", 0.0);
    const double cpu_start = process_cpu_seconds();
    auto cpu_seconds = [&] { return cpu_before + process_cpu_seconds() - cpu_start; };
    auto validate = [&] {
        ValidationOutcome outcome = stage.validate(step);
        last = outcome.score;
        const bool improved = last < best;
        if (improved) {
            best = last;
            files.save_best(step);
        }
        nlohmann::json record = std::move(outcome.fields);
        record["step"] = step;
        record["best"] = improved;
        record["seconds"] = elapsed();
        record["cpu_seconds"] = cpu_seconds();
        files.log(record);
        if (writes)
            spdlog::info("{}: step {} {} (best {:.4e})", options.what, step, outcome.summary, best);
    };

    if (stage.validates() && step == 0 && options.validate_first) validate();
    std::optional<ProgressBar> progress;
    if (writes) progress.emplace(options.steps, options.what);
    const int64_t first_step = step;
    int64_t saved_step = resumed_info.is_null() ? -1 : step;
    auto wants_stop = [&] {
        return (options.stop_after_seconds > 0 && elapsed() > options.stop_after_seconds) ||
               interrupt_requested();
    };
    while (step < options.steps) {
        const StepOutcome outcome = stage.step(step, wants_stop);
        ++step;
        if (!std::isfinite(outcome.loss))
            throw InternalError(
                fmt::format("{}: loss became {} at step {}", options.what, outcome.loss, step));
        if (options.check_every > 0 && step % options.check_every == 0 &&
            !group.identical(model.parameters()))
            throw InternalError(
                fmt::format("{}: the ranks' parameters differ after step {}", options.what, step));
        if (progress) progress->update(step, outcome.progress);
        if (step % options.log_every == 0) {
            nlohmann::json record = stage.log_fields();
            const double seconds = elapsed();
            record["step"] = step;
            record["seconds"] = seconds;
            record["steps_per_second"] = (step - first_step) / seconds;
            record["cpu_seconds"] = cpu_seconds();
            files.log(record);
        }
        const bool last_step = step == options.steps;
        if (stage.validates() && (step % options.val_every == 0 || last_step || outcome.stop))
            validate();
        if (step % options.checkpoint_every == 0 || last_step || outcome.stop) {
            files.save_state(step, best, cpu_seconds());
            saved_step = step;
        }
        if (outcome.stop) {
            if (writes)
                spdlog::info("{}: {} at step {}; checkpoint saved, continue with --resume",
                             options.what,
                             interrupt_requested() ? "interrupted" : "time limit reached", step);
            break;
        }
    }
    if (progress) progress->finish();
    // A fresh run that ends before its first step (steps = 0) still leaves its initial model.
    if (saved_step != step) files.save_state(step, best, cpu_seconds());
    // Every rank returns only once rank 0's last checkpoint is on disk.
    group.barrier();
    return {step, best, last};
}

}  // namespace pumeta
