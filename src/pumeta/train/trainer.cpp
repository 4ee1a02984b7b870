#include "pumeta/train/trainer.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "pumeta/core/blas_check.h"
#include "pumeta/core/error.h"
#include "pumeta/core/json_fields.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/nn/adam.h"
#include "pumeta/nn/gradients.h"
#include "pumeta/train/run_loop.h"
#include "pumeta/train/training_state.h"
#include "pumeta/train/validation.h"

namespace pumeta {

namespace {

template <class Self, class Visit>
void visit_fields(Self& c, Visit&& visit) {
    visit_run_settings(c, visit);
    visit("backbone", c.backbone);
    visit("batch_size", c.batch_size);
    visit_schedule(c.schedule, visit, "lr", "lr_decay_rate", "lr_decay_steps", "lr_min");
    visit("updates_per_batch", c.updates_per_batch);
    visit("val_patches", c.val_patches);
    visit("init_from", c.init_from);
}

}  // namespace

TrainConfig TrainConfig::from_json(const nlohmann::json& j) {
    TrainConfig c;
    read_fields(j, "train config", [&](auto&& visit) { visit_fields(c, visit); });
    check_run_settings(c, "train config", "batch_size", c.batch_size);
    check_schedule(c.schedule, "train config", "lr", "lr_decay_steps");
    if (c.updates_per_batch < 1)
        throw_input_error("train config", "'updates_per_batch' must be >= 1, found {}",
                          c.updates_per_batch);
    return c;
}

nlohmann::json TrainConfig::to_json() const {
    return write_fields([&](auto&& visit) { visit_fields(*this, visit); });
}

namespace {

/// Validation CD on this rank's shard of the validation set, combined over all ranks.
double distributed_validation_cd(const Backbone& model, const ValidationSet& val,
                                 ProcessGroup& group) {
    if (!group.enabled()) return validation_cd(model, val);
    int64_t n = val.input.size(0);
    Shard shard = shard_of(n, group.rank(), group.world_size());
    double part = 0;
    if (shard.size() > 0) {
        ValidationSet mine{val.input.slice(0, shard.begin, shard.end),
                           val.gt.slice(0, shard.begin, shard.end)};
        part = validation_cd(model, mine) * static_cast<double>(shard.size()) / n;
    }
    return group.sum({{"cd", at::scalar_tensor(part, at::kDouble)}})["cd"].item<double>();
}

/// Averages one step over the ranks in one collective: the gradients, the buffers (running
/// statistics each rank updated on its shard), the loss, and whether any rank wants to stop.
void all_reduce_step(ProcessGroup& group, ParamMap& grads, ParamMap& buffers, double& loss,
                     bool& stop) {
    // Every rank's loss reaches the same parameters (the same step draws the same curriculum).
    const at::TensorOptions like =
        grads.empty() ? at::TensorOptions().dtype(at::kFloat) : grads.begin()->second.options();
    ParamMap packet = grads;
    for (const auto& [name, b] : buffers) packet["buffer/" + name] = b;
    packet["~loss"] = at::scalar_tensor(loss, like);
    packet["~stop"] = at::scalar_tensor(stop ? 1 : 0, like);
    ParamMap mean = group.average(packet);
    for (auto& [name, g] : grads) g = mean.at(name);
    at::NoGradGuard no_grad;
    for (auto& [name, b] : buffers) b.copy_(mean.at("buffer/" + name));
    loss = mean.at("~loss").item<double>();
    stop = mean.at("~stop").item<double>() > 0;
}

/// Copies every parameter and buffer of the checkpoint at `path` whose name and shape match
/// the model's; the rest keep their initialisation. Logs what was kept fresh.
void initialise_from(Backbone& model, const std::string& path, bool log) {
    LoadedCheckpoint source = load_checkpoint(path);
    if (source.backbone->name() != model.name())
        throw_input_error(path, "init_from holds a {} model but the run trains {}",
                          source.backbone->name(), model.name());
    int64_t copied = 0;
    std::vector<std::string> fresh;
    auto copy_matching = [&](ParamMap& to, const ParamMap& from) {
        at::NoGradGuard no_grad;
        for (auto& [name, t] : to) {
            auto it = from.find(name);
            if (it != from.end() && it->second.sizes() == t.sizes()) {
                t.copy_(it->second);
                ++copied;
            } else {
                fresh.push_back(name);
            }
        }
    };
    copy_matching(model.parameters(), source.backbone->parameters());
    copy_matching(model.buffers(), source.backbone->buffers());
    if (copied == 0)
        throw_input_error(path, "no parameter matches the model in name and shape (init_from)");
    if (log)
        spdlog::info(
            "train: initialised {} tensors from {}; kept fresh: {}", copied, path,
            fresh.empty() ? std::string("none") : fmt::format("{}", fmt::join(fresh, ", ")));
}

/// The networks a backbone trains alongside itself (Backbone::make_auxiliary), with their own
/// Adam; kept in the run state under "aux/" (parameters) and "aux-adam/" (moments), never in
/// the model file.
class Auxiliary {
  public:
    Auxiliary(const Backbone& model, uint64_t seed)
        : params_(model.make_auxiliary(seed)), adam_(params_, AdamOptions{model.auxiliary_lr(0)}) {}

    bool empty() const { return params_.empty(); }
    const ParamMap& parameters() const { return params_; }

    /// Restores parameters and moments from a resumed state's optimiser tensors.
    void load(const ParamMap& optimizer, const nlohmann::json& info) {
        if (empty()) return;
        ParamMap moments;
        at::NoGradGuard no_grad;
        for (const auto& [name, t] : optimizer) {
            if (name.rfind(kParams, 0) == 0) param(params_, name.substr(kParams.size())).copy_(t);
            if (name.rfind(kMoments, 0) == 0) moments[name.substr(kMoments.size())] = t;
        }
        adam_.load_state(moments, info.at("aux_adam"));
    }

    void save(ParamMap& tensors, nlohmann::json& info) const {
        if (empty()) return;
        for (const auto& [name, p] : params_) tensors[kParams + name] = p.detach();
        for (const auto& [name, t] : adam_.state()) tensors[kMoments + name] = t;
        info["aux_adam"] = adam_.state_info();
    }

    /// What start_ranks_in_sync copies from rank 0.
    void add_to(ParamMap& state) {
        for (auto& [name, p] : params_) state[kParams + name] = p;
        for (auto& [name, t] : adam_.state()) state[kMoments + name] = t;
    }

    /// One Adam step on the auxiliary loss of the batch, averaged over the ranks; its value.
    /// `decay`: the run schedule's factor at this step (its learning rate over its initial
    /// one), applied to the backbone's auxiliary rate as the originals decay both optimisers.
    double step(const Backbone& model, const Batch& batch, int64_t step, double decay,
                ProcessGroup& group) {
        adam_.set_lr(model.auxiliary_lr(step) * decay);
        at::Tensor loss =
            model.auxiliary_loss(batch.input, batch.gt, model.parameters(), params_, step);
        ParamMap grads = gradients(loss, params_);
        double value = loss.item<double>();
        if (group.enabled()) {
            ParamMap packet = grads;
            packet["~loss"] = at::scalar_tensor(value, grads.begin()->second.options());
            ParamMap mean = group.average(packet);
            for (auto& [name, g] : grads) g = mean.at(name);
            value = mean.at("~loss").item<double>();
        }
        adam_.step(grads);
        return value;
    }

  private:
    inline static const std::string kParams = "aux/";
    inline static const std::string kMoments = "aux-adam/";
    ParamMap params_;
    Adam adam_;
};

/// Splits a resumed state's optimiser tensors: the backbone's Adam's, without the auxiliary
/// networks' ("aux/", "aux-adam/").
ParamMap backbone_moments(const ParamMap& optimizer) {
    ParamMap moments;
    for (const auto& [name, t] : optimizer)
        if (name.rfind("aux/", 0) != 0 && name.rfind("aux-adam/", 0) != 0) moments[name] = t;
    return moments;
}

/// Supervised pretraining's step (Adam on the backbone's loss, then the auxiliary networks'
/// step when the backbone has any) and validation (CD on held-out patches).
class SupervisedStage final : public RunStage {
  public:
    SupervisedStage(const TrainConfig& config, Backbone& model, ProcessGroup& group,
                    const TrainingState& opened)
        : config_(config),
          model_(model),
          group_(group),
          data_(config, config.batch_size, config.val_patches, model, group),
          adam_(model.parameters(), AdamOptions{config.schedule.lr}),
          auxiliary_(model, config.seed) {
        for (const auto& [name, p] : model.parameters())
            adam_.set_group(name, model.optimizer_group(name));
        int64_t step = 0;
        if (!opened.info.is_null()) {
            adam_.load_state(backbone_moments(opened.optimizer), opened.info.at("adam"));
            auxiliary_.load(opened.optimizer, opened.info);
            step = opened.info.at("step");
            if (opened.info.value("last_val_cd", nlohmann::json()).is_number())
                last_val_ = opened.info["last_val_cd"];
            data_.loader.seek(opened.info.at("loader_position"));
        }
        ParamMap adam_state;
        for (auto& [name, t] : adam_.state()) adam_state["adam/" + name] = t;
        auxiliary_.add_to(adam_state);
        start_ranks_in_sync(group, model,
                            {{"step", step},
                             {"loader_position", data_.loader.position()},
                             {"adam_steps", adam_.steps()}},
                            adam_state);
    }

    StepOutcome step(int64_t step, const std::function<bool()>& wants_stop) override {
        Batch batch = data_.loader.next();
        adam_.set_lr(config_.schedule.at(step) * model_.learning_rate_factor(step));
        const int64_t updates = config_.updates_per_batch;
        double loss_value = 0;
        bool stop = false;
        // Buffers (running statistics, Dis-PU's step count) move once per batch.
        model_.update_buffers(batch.input, model_.parameters());
        for (int64_t update = 0; update < updates; ++update) {
            // training_terms: loss_terms unless the backbone trains otherwise (auxiliary
            // networks, a curriculum).
            LossTerms terms = model_.training_terms(batch.input, batch.gt, model_.parameters(),
                                                    auxiliary_.parameters(), step);
            at::Tensor loss = sum_of(terms);
            // Only the parameters this step's loss reaches: a curriculum's frozen levels keep
            // their weights and Adam moments, as the originals' optimisers over a variable list.
            ParamMap grads = used_gradients(loss, model_.parameters());
            double value = loss.item<double>();
            if (terms.size() > 1)
                for (const auto& [name, term] : terms)
                    term_sums_[name] += term.item<double>() / double(updates);
            // The ranks agree on stopping once per batch, with the last update's reduction.
            stop = update + 1 == updates && wants_stop();
            if (group_.enabled()) all_reduce_step(group_, grads, model_.buffers(), value, stop);
            adam_.step(grads);
            loss_value += value / double(updates);
        }
        if (!auxiliary_.empty())
            auxiliary_loss_sum_ += auxiliary_.step(
                model_, batch, step, config_.schedule.at(step) / config_.schedule.lr, group_);
        loss_sum_ += loss_value;
        ++loss_count_;
        return {loss_value, stop, fmt::format("loss {:.3e} val {:.3e}", loss_value, last_val_)};
    }

    nlohmann::json log_fields() override {
        nlohmann::json fields = {{"loss", loss_sum_ / loss_count_}, {"lr", adam_.lr()}};
        // This process's share of the batch only, when distributed.
        for (auto& [name, sum] : term_sums_) {
            fields["loss_" + name] = sum / loss_count_;
            sum = 0;
        }
        if (!auxiliary_.empty()) fields["auxiliary_loss"] = auxiliary_loss_sum_ / loss_count_;
        auxiliary_loss_sum_ = 0;
        loss_sum_ = 0;
        loss_count_ = 0;
        return fields;
    }

    bool validates() const override { return data_.val.has_value(); }

    ValidationOutcome validate(int64_t) override {
        last_val_ = distributed_validation_cd(model_, *data_.val, group_);
        return {last_val_,
                {{"val_cd", last_val_}, {"input_cd", data_.val->input_cd}},
                fmt::format("val CD {:.4e} (input {:.4e})", last_val_, data_.val->input_cd)};
    }

    void save_state(ParamMap& tensors, nlohmann::json& info) const override {
        tensors = adam_.state();
        info["adam"] = adam_.state_info();
        auxiliary_.save(tensors, info);
        info["last_val_cd"] = last_val_;
        info["loader_position"] = data_.loader.position();
    }

    nlohmann::json model_extra(int64_t step) const override {
        return {{"train_config", config_.to_json()},
                {"sampler", config_.sampler},
                {"step", step},
                {"val_cd", last_val_}};
    }

    double last_val() const { return last_val_; }

  private:
    const TrainConfig& config_;
    Backbone& model_;
    ProcessGroup& group_;
    RunData data_;
    Adam adam_;
    Auxiliary auxiliary_;
    double last_val_ = std::numeric_limits<double>::infinity();
    double loss_sum_ = 0, auxiliary_loss_sum_ = 0;
    std::map<std::string, double> term_sums_;  // of backbones whose loss has several terms
    int64_t loss_count_ = 0;
};

}  // namespace

TrainResult train(const TrainConfig& config, bool resume, double stop_after_seconds,
                  const std::vector<std::string>& allow_changes) {
    check_blas();
    ProcessGroup group(config.distributed);
    // Rank 0 alone writes the run directory; the others only read it when resuming.
    const bool writes = group.is_main();
    TrainingState opened =
        open_run(config.run_dir, {resume, allow_changes}, writes, "train", config.to_json(), [&] {
            if (config.backbone.is_null())
                throw_input_error("train config", "'backbone' is required");
            std::unique_ptr<Backbone> fresh = make_backbone(config.backbone);
            if (!config.init_from.empty()) initialise_from(*fresh, config.init_from, writes);
            return fresh;
        });
    SupervisedStage stage(config, *opened.model, group, opened);
    RunLoopOptions loop = loop_options(config, "train", config.to_json(), stop_after_seconds);
    loop.best_key = "best_val_cd";
    RunLoopResult result = run_loop(*opened.model, stage, loop, group, opened.info);
    return {result.steps, result.best_score, stage.last_val()};
}

}  // namespace pumeta
