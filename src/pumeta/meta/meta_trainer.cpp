#include "pumeta/meta/meta_trainer.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>

#include "pumeta/core/blas_check.h"
#include "pumeta/core/error.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/core/json_fields.h"
#include "pumeta/core/progress.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/nn/adam.h"
#include "pumeta/train/training_state.h"
#include "pumeta/train/validation.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

template <class Self, class Visit>
void visit_fields(Self& c, Visit&& visit) {
    visit("init", c.init);
    visit("train_data", c.train_data);
    visit("val_data", c.val_data);
    visit("run_dir", c.run_dir);
    visit("meta", c.meta);
    visit("tasks_per_batch", c.tasks_per_batch);
    visit("steps", c.steps);
    visit("outer_lr", c.outer_lr);
    visit("outer_lr_decay", c.outer_lr_decay);
    visit("outer_lr_decay_steps", c.outer_lr_decay_steps);
    visit("step_size_lr", c.step_size_lr);
    visit("sampler", c.sampler);
    visit("augment", c.augment);
    visit("log_every", c.log_every);
    visit("val_every", c.val_every);
    visit("val_tasks", c.val_tasks);
    visit("checkpoint_every", c.checkpoint_every);
    visit("seed", c.seed);
    visit("distributed", c.distributed);
}

}  // namespace

MetaTrainConfig MetaTrainConfig::from_json(const nlohmann::json& j) {
    MetaTrainConfig c;
    read_fields(j, "meta-train config", [&](auto&& visit) { visit_fields(c, visit); });
    const std::pair<const char*, const std::string*> required[] = {
        {"init", &c.init}, {"train_data", &c.train_data}, {"run_dir", &c.run_dir}};
    for (const auto& [key, value] : required)
        if (value->empty()) throw_input_error("meta-train config", "'{}' is required", key);
    if (c.tasks_per_batch < 1) throw_input_error("meta-train config", "tasks_per_batch < 1");
    if (c.tasks_per_batch % c.distributed.world_size != 0)
        throw_input_error("meta-train config",
                          "tasks_per_batch {} does not split evenly over {} processes",
                          c.tasks_per_batch, c.distributed.world_size);
    parse_input_sampler(c.sampler);
    if (c.meta.inner_optimizer == "adam" && c.steps > 0)
        throw_input_error("meta-train config",
                          "meta.inner_optimizer \"adam\" is for test-time adaptation only (steps "
                          "= 0 validates with it)");
    return c;
}

nlohmann::json MetaTrainConfig::to_json() const {
    return write_fields([&](auto&& visit) { visit_fields(*this, visit); });
}

namespace {

/// Validation on this rank's shard of the held-out tasks, combined over all ranks.
AdaptationScore score_adaptation(const Backbone& model, const ValidationSet& val,
                                 const MetaOptions& meta, const StepSizes& step_sizes,
                                 uint64_t seed, ProcessGroup& group) {
    AdaptationScore score;
    int64_t n = val.input.size(0);
    Shard shard = shard_of(n, group.rank(), group.world_size());
    std::vector<at::Tensor> before, after;
    for (int64_t i = shard.begin; i < shard.end; ++i) {
        at::Tensor x = val.input.slice(0, i, i + 1);
        at::Tensor x_down = model.downsample(x, seed + static_cast<uint64_t>(i));
        std::vector<double> losses;
        ParamMap adapted = adapt(model, model.parameters(), x_down, x, meta, step_sizes,
                                 /*create_graph=*/false, &losses);
        score.inner_loss_before += losses.front() / n;
        score.inner_loss_after += losses.back() / n;
        // The task's own supervised pair, and the next task's (another mesh, mostly; the same
        // task when there is only one).
        const int64_t j = (i + 1) % n;
        std::vector<double> cosines =
            first_step_alignment(model, model.parameters(), x_down, x,
                                 {{x, val.gt.slice(0, i, i + 1)},
                                  {val.input.slice(0, j, j + 1), val.gt.slice(0, j, j + 1)}},
                                 meta, step_sizes);
        score.alignment += cosines[0] / n;
        score.alignment_other += cosines[1] / n;
        at::NoGradGuard no_grad;
        before.push_back(model.upsample(x));
        after.push_back(model.upsample(x, adapted));
    }
    at::Tensor gt = val.gt.slice(0, shard.begin, shard.end);
    double share = static_cast<double>(shard.size()) / n;
    if (shard.size() > 0) {
        score.cd_before = mean_chamfer(at::cat(before), gt) * share;
        score.cd_after = mean_chamfer(at::cat(after), gt) * share;
    }
    if (!group.enabled()) return score;
    auto scalar = [](double v) { return at::scalar_tensor(v, at::kDouble); };
    ParamMap totals = group.sum({{"cd_before", scalar(score.cd_before)},
                                 {"cd_after", scalar(score.cd_after)},
                                 {"inner_before", scalar(score.inner_loss_before)},
                                 {"inner_after", scalar(score.inner_loss_after)},
                                 {"alignment", scalar(score.alignment)},
                                 {"alignment_other", scalar(score.alignment_other)}});
    return {totals["cd_before"].item<double>(),    totals["cd_after"].item<double>(),
            totals["inner_before"].item<double>(), totals["inner_after"].item<double>(),
            totals["alignment"].item<double>(),    totals["alignment_other"].item<double>()};
}

/// Combines one outer step over the ranks in one collective: the gradients and losses as
/// means over every rank's kept tasks (a rank that dropped tasks weighs less), the dropped
/// tasks summed, and whether any rank wants to stop (so that all stop at the same step).
void all_reduce_step(ProcessGroup& group, MetaStepResult& r, bool& stop) {
    stop = unpack_step_sum(group.sum(pack_step_sum(r, stop)), r);
}

}  // namespace

MetaTrainResult meta_train(const MetaTrainConfig& config, bool resume, double stop_after_seconds,
                           const std::vector<std::string>& allow_changes) {
    check_blas_speed();
    ProcessGroup group(config.distributed);
    // Rank 0 alone writes the run directory; the others only read it when resuming.
    bool writes = group.is_main();
    fs::path state_file = fs::path(config.run_dir) / "state.ckpt";
    fs::path log_file = fs::path(config.run_dir) / "log.jsonl";
    TrainingState opened =
        open_run(config.run_dir, {resume, allow_changes}, writes, "meta-train", config.to_json(),
                 [&] { return load_checkpoint(config.init).backbone; });
    std::unique_ptr<Backbone> model = std::move(opened.model);
    nlohmann::json info = opened.info;
    ParamMap optimizer_state = std::move(opened.optimizer);
    StepSizes step_sizes;
    if (config.meta.learn_inner_lr) {
        step_sizes = make_step_sizes(*model, config.meta);
        if (info.contains("step_sizes"))
            for (auto& [name, a] : step_sizes_from_json(info["step_sizes"]))
                step_sizes.at(name) = a.clone().set_requires_grad(true);
    }

    PatchSet train_set = load_patch_set(config.train_data);
    LoaderOptions loader_options;
    loader_options.batch_size = config.tasks_per_batch;
    loader_options.sampler = parse_input_sampler(config.sampler);
    loader_options.augment = config.augment;
    loader_options.seed = config.seed;
    loader_options.shard_index = group.rank();
    loader_options.shard_count = group.world_size();
    PatchLoader loader(train_set, loader_options);
    // Task n of a batch is the n-th of the whole batch: its X↓ seed must not depend on W.
    auto first_task =
        static_cast<uint64_t>(config.tasks_per_batch / group.world_size() * group.rank());
    std::optional<ValidationSet> val;
    if (!config.val_data.empty())
        val = make_validation_set(load_patch_set(config.val_data), config.val_tasks,
                                  loader_options.sampler, config.seed);

    Adam outer(model->parameters(), AdamOptions{config.outer_lr});
    std::optional<Adam> step_size_optimizer;
    if (config.meta.learn_inner_lr)
        step_size_optimizer.emplace(step_sizes,
                                    AdamOptions{config.step_size_lr * config.meta.inner_lr});
    int64_t step = 0;
    double best = std::numeric_limits<double>::infinity();
    AdaptationScore last;
    if (!info.is_null()) {
        ParamMap theta_state, alpha_state;
        for (auto& [name, t] : optimizer_state)
            (name.rfind("alpha:", 0) == 0 ? alpha_state[name.substr(6)] : theta_state[name]) = t;
        outer.load_state(theta_state, info.at("adam"));
        if (step_size_optimizer)
            step_size_optimizer->load_state(alpha_state, info.at("adam_alpha"));
        step = info.at("step");
        // A run without validation stores its initial infinity, which JSON writes as null.
        if (info.value("best_cd_after", nlohmann::json()).is_number()) best = info["best_cd_after"];
        loader.seek(info.at("loader_position"));
    }
    {
        ParamMap state;
        for (auto& [name, p] : model->parameters()) state["theta/" + name] = p;
        for (auto& [name, b] : model->buffers()) state["buffer/" + name] = b;
        for (auto& [name, t] : outer.state()) state["adam/" + name] = t;
        for (auto& [name, a] : step_sizes) state["alpha/" + name] = a;
        if (step_size_optimizer)
            for (auto& [name, t] : step_size_optimizer->state()) state["adam_alpha/" + name] = t;
        start_in_sync(
            group,
            {{"step", step}, {"loader_position", loader.position()}, {"adam_steps", outer.steps()}},
            state);
    }

    auto model_extra = [&] {
        nlohmann::json meta = config.meta.to_json();
        return nlohmann::json{
            {"meta", meta},
            {"step_sizes", step_sizes_to_json(step_sizes)},
            {"meta_train_config", config.to_json()},
            {"sampler", config.sampler},
            {"step", step},
            {"val", {{"cd_before", last.cd_before}, {"cd_after", last.cd_after}}}};
    };
    auto save_state = [&] {
        ParamMap tensors = outer.state();
        nlohmann::json state_info = {{"step", step},
                                     {"adam", outer.state_info()},
                                     {"best_cd_after", best},
                                     {"loader_position", loader.position()},
                                     {"step_sizes", step_sizes_to_json(step_sizes)},
                                     {kRunConfigKey, comparable_config(config.to_json())}};
        if (step_size_optimizer) {
            for (auto& [name, t] : step_size_optimizer->state()) tensors["alpha:" + name] = t;
            state_info["adam_alpha"] = step_size_optimizer->state_info();
        }
        save_training_state(state_file.string(), *model, tensors, state_info);
        save_checkpoint((fs::path(config.run_dir) / "model.pt").string(), *model, model_extra());
    };
    auto validate = [&] {
        MetaOptions meta = config.meta;
        last = score_adaptation(*model, *val, meta, step_sizes, config.seed + 99991, group);
        bool improved = last.cd_after < best;
        if (improved) best = last.cd_after;
        if (!writes) return;
        if (improved)
            save_checkpoint((fs::path(config.run_dir) / "best.pt").string(), *model, model_extra());
        append_log(log_file.string(), {{"step", step},
                                       {"val_cd_before", last.cd_before},
                                       {"val_cd_after", last.cd_after},
                                       {"val_inner_before", last.inner_loss_before},
                                       {"val_inner_after", last.inner_loss_after},
                                       {"val_alignment", last.alignment},
                                       {"val_alignment_other", last.alignment_other},
                                       {"best", improved}});
        spdlog::info(
            "meta-train: step {} val CD {:.4e} -> {:.4e} after adaptation (inner "
            "{:.4e} -> {:.4e}, first-step alignment {:+.3f}, with another task's {:+.3f})",
            step, last.cd_before, last.cd_after, last.inner_loss_before, last.inner_loss_after,
            last.alignment, last.alignment_other);
    };

    if (val && step == 0) validate();
    auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    std::optional<ProgressBar> progress;
    if (writes) progress.emplace(config.steps, "meta-train");
    int64_t first_step = step;
    while (step < config.steps) {
        Batch batch = loader.next();
        outer.set_lr(config.outer_lr *
                     std::pow(config.outer_lr_decay,
                              static_cast<double>(step) / config.outer_lr_decay_steps));
        MetaStepResult r = meta_gradient(
            *model, batch.input, batch.gt, config.meta, step_sizes,
            config.seed * 1000003 + static_cast<uint64_t>(step) * 64 + first_task, step);
        bool stop =
            (stop_after_seconds > 0 && elapsed() > stop_after_seconds) || interrupt_requested();
        if (group.enabled()) all_reduce_step(group, r, stop);
        if (!std::isfinite(r.outer_loss))
            throw InternalError(
                fmt::format("meta-train: outer loss became {} at step {}", r.outer_loss, step));
        outer.step(r.grads);
        if (step_size_optimizer) step_size_optimizer->step(r.step_size_grads);
        ++step;
        if (config.distributed.check_every > 0 && step % config.distributed.check_every == 0 &&
            !group.identical(model->parameters()))
            throw InternalError(
                fmt::format("meta-train: the ranks' parameters differ after step {}", step));
        if (progress)
            progress->update(step, fmt::format("outer {:.3e} (unadapted {:.3e})", r.outer_loss,
                                               r.outer_loss_before));
        if (writes && step % config.log_every == 0)
            append_log(log_file.string(), {{"step", step},
                                           {"outer_loss", r.outer_loss},
                                           {"outer_loss_before", r.outer_loss_before},
                                           {"inner_loss_before", r.inner_loss_before},
                                           {"inner_loss_after", r.inner_loss_after},
                                           {"dropped_tasks", r.dropped_tasks},
                                           {"lr", outer.lr()},
                                           {"seconds", elapsed()},
                                           {"steps_per_second", (step - first_step) / elapsed()}});
        if (val && (step % config.val_every == 0 || step == config.steps || stop)) validate();
        if (writes && (step % config.checkpoint_every == 0 || step == config.steps || stop))
            save_state();
        if (stop) {
            if (writes)
                spdlog::info("meta-train: {} at step {}; checkpoint saved, continue with --resume",
                             interrupt_requested() ? "interrupted" : "time limit reached", step);
            break;
        }
    }
    if (progress) progress->finish();
    // Every rank returns only once rank 0's last checkpoint is on disk.
    group.barrier();
    return {step, last, best};
}

}  // namespace pumeta
