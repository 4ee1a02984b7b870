#include "pumeta/meta/meta_trainer.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <utility>

#include "pumeta/core/blas_check.h"
#include "pumeta/core/error.h"
#include "pumeta/core/hash.h"
#include "pumeta/core/json_fields.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/nn/adam.h"
#include "pumeta/train/run_loop.h"
#include "pumeta/train/training_state.h"
#include "pumeta/train/validation.h"

namespace pumeta {

namespace {

template <class Self, class Visit>
void visit_fields(Self& c, Visit&& visit) {
    visit_run_settings(c, visit);
    visit("init", c.init);
    visit("meta", c.meta);
    visit("tasks_per_batch", c.tasks_per_batch);
    visit_schedule(c.outer, visit, "outer_lr", "outer_lr_decay", "outer_lr_decay_steps");
    visit("step_size_lr", c.step_size_lr);
    visit("val_tasks", c.val_tasks);
    visit("task_ratios", c.task_ratios);
}

}  // namespace

MetaTrainConfig MetaTrainConfig::from_json(const nlohmann::json& j) {
    MetaTrainConfig c;
    read_fields(j, "meta-train config", [&](auto&& visit) { visit_fields(c, visit); });
    if (c.init.empty()) throw_input_error("meta-train config", "'init' is required");
    check_run_settings(c, "meta-train config", "tasks_per_batch", c.tasks_per_batch);
    check_schedule(c.outer, "meta-train config", "outer_lr", "outer_lr_decay_steps");
    for (int64_t ratio : c.task_ratios)
        if (ratio < 2)
            throw_input_error("meta-train config", "'task_ratios': ratio {} must be at least 2",
                              ratio);
    return c;
}

nlohmann::json MetaTrainConfig::to_json() const {
    return write_fields([&](auto&& visit) { visit_fields(*this, visit); });
}

namespace {

/// Task i of the validation set: the model at the task's ratio and its input X.
using ValidationTask =
    std::function<std::pair<const Backbone*, at::Tensor>(int64_t i, const at::Tensor& gt)>;

/// Validation on this rank's shard of the held-out tasks, combined over all ranks.
AdaptationScore score_adaptation(const ValidationTask& task, const ValidationSet& val,
                                 const MetaOptions& meta, const StepSizes& step_sizes,
                                 uint64_t seed, ProcessGroup& group) {
    AdaptationScore score;
    int64_t n = val.input.size(0);
    Shard shard = shard_of(n, group.rank(), group.world_size());
    // CD per task, then the mean: tasks at several ratios give outputs of several sizes.
    int64_t diverged = 0;
    for (int64_t i = shard.begin; i < shard.end; ++i) {
        at::Tensor gt_i = val.gt.slice(0, i, i + 1);
        auto [model_at_ratio, x] = task(i, gt_i);
        const Backbone& model = *model_at_ratio;
        at::Tensor x_down = model.downsample(x, seed + static_cast<uint64_t>(i));
        std::vector<double> losses;
        ParamMap adapted =
            adapt(model, model.parameters(), x_down, x, meta.inner_loop(), step_sizes,
                  /*create_graph=*/false, &losses);
        // As at test time (inference/upsample.cpp): a diverged task keeps θ, instead of
        // scoring whatever non-finite weights happen to select.
        if (inner_loop_diverged(losses)) {
            ++diverged;
            adapted = model.parameters();
            losses.back() = losses.front();
        }
        score.inner_loss_before += losses.front() / n;
        score.inner_loss_after += losses.back() / n;
        at::NoGradGuard no_grad;
        score.cd_before += mean_chamfer(model.upsample(x), gt_i) / n;
        score.cd_after += mean_chamfer(model.upsample(x, adapted), gt_i) / n;
    }
    if (diverged > 0)
        spdlog::warn("validation: adaptation diverged on {} of {} tasks; scored unadapted",
                     diverged, shard.size());
    if (!group.enabled()) return score;
    auto scalar = [](double v) { return at::scalar_tensor(v, at::kDouble); };
    ParamMap totals = group.sum({{"cd_before", scalar(score.cd_before)},
                                 {"cd_after", scalar(score.cd_after)},
                                 {"inner_before", scalar(score.inner_loss_before)},
                                 {"inner_after", scalar(score.inner_loss_after)}});
    return {totals["cd_before"].item<double>(), totals["cd_after"].item<double>(),
            totals["inner_before"].item<double>(), totals["inner_after"].item<double>()};
}

/// Combines one outer step over the ranks in one collective: the gradients and losses as
/// means over every rank's kept tasks (a rank that dropped tasks weighs less), the dropped
/// tasks summed, and whether any rank wants to stop (so that all stop at the same step).
void all_reduce_step(ProcessGroup& group, MetaStepResult& r, bool& stop) {
    stop = unpack_step_sum(group.sum(pack_step_sum(r, stop)), r);
}

/// Meta-training's step (Algorithm 1: the outer Adam step on the adapted tasks' loss, and
/// Meta-SGD's step sizes) and validation (CD after adapting to held-out tasks).
class MetaStage final : public RunStage {
  public:
    MetaStage(const MetaTrainConfig& config, Backbone& model, ProcessGroup& group,
              const TrainingState& opened)
        : config_(config),
          model_(model),
          group_(group),
          data_(config, config.tasks_per_batch, config.val_tasks, model, group),
          // Task n of a batch is the n-th of the whole batch: its X↓ seed must not depend on W.
          first_task_(
              static_cast<uint64_t>(config.tasks_per_batch / group.world_size() * group.rank())),
          outer_(model.parameters(), AdamOptions{config.outer.lr}) {
        for (int64_t ratio : config.task_ratios) add_task_ratio(ratio);
        const nlohmann::json& info = opened.info;
        if (config.meta.learn_inner_lr) {
            step_sizes_ = make_step_sizes(model, config.meta);
            if (info.contains("step_sizes"))
                for (auto& [name, a] : step_sizes_from_json(info["step_sizes"]))
                    step_sizes_.at(name) = a.clone().set_requires_grad(true);
            step_size_optimizer_.emplace(step_sizes_,
                                         AdamOptions{config.step_size_lr * config.meta.inner_lr});
        }
        int64_t step = 0;
        if (!info.is_null()) {
            ParamMap theta_state, alpha_state;
            for (auto& [name, t] : opened.optimizer)
                (name.rfind("alpha:", 0) == 0 ? alpha_state[name.substr(6)] : theta_state[name]) =
                    t;
            outer_.load_state(theta_state, info.at("adam"));
            if (step_size_optimizer_)
                step_size_optimizer_->load_state(alpha_state, info.at("adam_alpha"));
            step = info.at("step");
            data_.loader.seek(info.at("loader_position"));
        }
        ParamMap state;
        for (auto& [name, t] : outer_.state()) state["adam/" + name] = t;
        for (auto& [name, a] : step_sizes_) state["alpha/" + name] = a;
        if (step_size_optimizer_)
            for (auto& [name, t] : step_size_optimizer_->state()) state["adam_alpha/" + name] = t;
        start_ranks_in_sync(group, model,
                            {{"step", step},
                             {"loader_position", data_.loader.position()},
                             {"adam_steps", outer_.steps()}},
                            state);
    }

    StepOutcome step(int64_t step, const std::function<bool()>& wants_stop) override {
        Batch batch = data_.loader.next();
        outer_.set_lr(config_.outer.at(step));
        const uint64_t seed =
            config_.seed * 1000003 + static_cast<uint64_t>(step) * 64 + first_task_;
        const Backbone* model = &model_;
        at::Tensor input = batch.input;
        if (!config_.task_ratios.empty()) {
            const uint64_t pick = derive_seed(config_.seed, "task-ratio/" + std::to_string(step));
            model = &at_ratio(config_.task_ratios[pick % config_.task_ratios.size()]);
            input = model->downsample(batch.gt, derive_seed(seed, "task-input"));
        }
        last_step_ = meta_gradient(*model, input, batch.gt, config_.meta, step_sizes_, seed, step);
        bool stop = wants_stop();
        if (group_.enabled()) all_reduce_step(group_, last_step_, stop);
        if (std::isfinite(last_step_.outer_loss)) {
            outer_.step(last_step_.grads);
            if (step_size_optimizer_) step_size_optimizer_->step(last_step_.step_size_grads);
        }
        return {last_step_.outer_loss, stop,
                fmt::format("outer {:.3e} (unadapted {:.3e})", last_step_.outer_loss,
                            last_step_.outer_loss_before)};
    }

    nlohmann::json log_fields() override {
        return {{"outer_loss", last_step_.outer_loss},
                {"outer_loss_before", last_step_.outer_loss_before},
                {"inner_loss_before", last_step_.inner_loss_before},
                {"inner_loss_after", last_step_.inner_loss_after},
                {"dropped_tasks", last_step_.dropped_tasks},
                {"lr", outer_.lr()}};
    }

    bool validates() const override { return data_.val.has_value(); }

    ValidationOutcome validate(int64_t) override {
        const uint64_t seed = config_.seed + 99991;
        ValidationTask task = [&](int64_t i,
                                  const at::Tensor& gt) -> std::pair<const Backbone*, at::Tensor> {
            if (config_.task_ratios.empty()) return {&model_, data_.val->input.slice(0, i, i + 1)};
            const Backbone& model =
                at_ratio(config_.task_ratios[size_t(i) % config_.task_ratios.size()]);
            return {&model, model.downsample(gt, derive_seed(seed + uint64_t(i), "task-input"))};
        };
        last_ = score_adaptation(task, *data_.val, config_.meta, step_sizes_, seed, group_);
        return {last_.cd_after,
                {{"val_cd_before", last_.cd_before},
                 {"val_cd_after", last_.cd_after},
                 {"val_inner_before", last_.inner_loss_before},
                 {"val_inner_after", last_.inner_loss_after}},
                fmt::format("val CD {:.4e} -> {:.4e} after adaptation (inner {:.4e} -> {:.4e})",
                            last_.cd_before, last_.cd_after, last_.inner_loss_before,
                            last_.inner_loss_after)};
    }

    void save_state(ParamMap& tensors, nlohmann::json& info) const override {
        tensors = outer_.state();
        info["adam"] = outer_.state_info();
        info["loader_position"] = data_.loader.position();
        info["step_sizes"] = step_sizes_to_json(step_sizes_);
        if (step_size_optimizer_) {
            for (auto& [name, t] : step_size_optimizer_->state()) tensors["alpha:" + name] = t;
            info["adam_alpha"] = step_size_optimizer_->state_info();
        }
    }

    nlohmann::json model_extra(int64_t step) const override {
        return {{"meta", config_.meta.to_json()},
                {"step_sizes", step_sizes_to_json(step_sizes_)},
                {"meta_train_config", config_.to_json()},
                {"sampler", config_.sampler},
                {"step", step},
                {"val", {{"cd_before", last_.cd_before}, {"cd_after", last_.cd_after}}}};
    }

    const AdaptationScore& last() const { return last_; }

  private:
    /// The model rebuilt at `ratio` holding the same parameter and buffer tensors as model_
    /// (pumeta::share_weights_at), so that its losses' gradients are model_'s and the outer
    /// optimiser's in-place updates reach it.
    void add_task_ratio(int64_t ratio) {
        if (ratio == model_.ratio() || at_ratio_.count(ratio)) return;
        std::unique_ptr<Backbone> rebuilt = pumeta::share_weights_at(model_, ratio);
        if (!rebuilt)
            throw_input_error("meta-train config",
                              "'task_ratios': the {} model of '{}' does not serve {}x",
                              model_.name(), config_.init, ratio);
        at_ratio_.emplace(ratio, std::move(rebuilt));
    }

    const Backbone& at_ratio(int64_t ratio) const {
        return ratio == model_.ratio() ? model_ : *at_ratio_.at(ratio);
    }

    const MetaTrainConfig& config_;
    Backbone& model_;
    ProcessGroup& group_;
    RunData data_;
    const uint64_t first_task_;
    StepSizes step_sizes_;
    Adam outer_;
    std::optional<Adam> step_size_optimizer_;
    std::map<int64_t, std::unique_ptr<Backbone>> at_ratio_;
    MetaStepResult last_step_;
    AdaptationScore last_;
};

}  // namespace

MetaTrainResult meta_train(const MetaTrainConfig& config, bool resume, double stop_after_seconds,
                           const std::vector<std::string>& allow_changes) {
    check_blas();
    ProcessGroup group(config.distributed);
    // Rank 0 alone writes the run directory; the others only read it when resuming.
    TrainingState opened =
        open_run(config.run_dir, {resume, allow_changes}, group.is_main(), "meta-train",
                 config.to_json(), [&] { return load_checkpoint(config.init).backbone; });
    MetaStage stage(config, *opened.model, group, opened);
    RunLoopOptions loop = loop_options(config, "meta-train", config.to_json(), stop_after_seconds);
    loop.validate_first = true;
    loop.best_key = "best_cd_after";
    RunLoopResult result = run_loop(*opened.model, stage, loop, group, opened.info);
    return {result.steps, stage.last(), result.best_score};
}

}  // namespace pumeta
