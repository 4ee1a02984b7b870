#include "pumeta/train/trainer.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "pumeta/core/blas_check.h"
#include "pumeta/core/error.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/core/json_fields.h"
#include "pumeta/core/progress.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/nn/adam.h"
#include "pumeta/nn/gradients.h"
#include "pumeta/train/training_state.h"
#include "pumeta/train/validation.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

template <class Self, class Visit>
void visit_fields(Self& c, Visit&& visit) {
    visit("backbone", c.backbone);
    visit("train_data", c.train_data);
    visit("val_data", c.val_data);
    visit("run_dir", c.run_dir);
    visit("batch_size", c.batch_size);
    visit("steps", c.steps);
    visit("lr", c.lr);
    visit("lr_decay_rate", c.lr_decay_rate);
    visit("lr_decay_steps", c.lr_decay_steps);
    visit("lr_min", c.lr_min);
    visit("sampler", c.sampler);
    visit("augment", c.augment);
    visit("log_every", c.log_every);
    visit("val_every", c.val_every);
    visit("val_patches", c.val_patches);
    visit("checkpoint_every", c.checkpoint_every);
    visit("seed", c.seed);
    visit("init_from", c.init_from);
    visit("distributed", c.distributed);
}

}  // namespace

TrainConfig TrainConfig::from_json(const nlohmann::json& j) {
    TrainConfig c;
    read_fields(j, "train config", [&](auto&& visit) { visit_fields(c, visit); });
    if (c.run_dir.empty()) throw_input_error("train config", "'run_dir' is required");
    if (c.train_data.empty()) throw_input_error("train config", "'train_data' is required");
    if (c.batch_size < 1 || c.steps < 0 || c.lr <= 0)
        throw_input_error("train config", "batch_size, steps and lr must be positive");
    if (c.batch_size % c.distributed.world_size != 0)
        throw_input_error("train config", "batch_size {} does not split evenly over {} processes",
                          c.batch_size, c.distributed.world_size);
    parse_input_sampler(c.sampler);
    return c;
}

nlohmann::json TrainConfig::to_json() const {
    return write_fields([&](auto&& visit) { visit_fields(*this, visit); });
}

namespace {

double learning_rate(const TrainConfig& c, int64_t step) {
    double lr = c.lr * std::pow(c.lr_decay_rate, static_cast<double>(step) / c.lr_decay_steps);
    return std::max(lr, c.lr_min);
}

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
    const at::Tensor& like = grads.begin()->second;
    ParamMap packet = grads;
    for (const auto& [name, b] : buffers) packet["buffer/" + name] = b;
    packet["~loss"] = at::scalar_tensor(loss, like.options());
    packet["~stop"] = at::scalar_tensor(stop ? 1 : 0, like.options());
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

}  // namespace

TrainResult train(const TrainConfig& config, bool resume, double stop_after_seconds,
                  const std::vector<std::string>& allow_changes) {
    check_blas_speed();
    ProcessGroup group(config.distributed);
    // Rank 0 alone writes the run directory; the others only read it when resuming.
    bool writes = group.is_main();
    fs::path state_file = fs::path(config.run_dir) / "state.ckpt";
    fs::path log_file = fs::path(config.run_dir) / "log.jsonl";
    TrainingState opened =
        open_run(config.run_dir, {resume, allow_changes}, writes, "train", config.to_json(), [&] {
            if (config.backbone.is_null())
                throw_input_error("train config", "'backbone' is required");
            std::unique_ptr<Backbone> fresh = make_backbone(config.backbone);
            if (!config.init_from.empty()) initialise_from(*fresh, config.init_from, writes);
            return fresh;
        });
    std::unique_ptr<Backbone> model = std::move(opened.model);
    nlohmann::json state_info = opened.info;
    ParamMap optimizer_state = std::move(opened.optimizer);
    PatchSet train_set = load_patch_set(config.train_data);
    if (train_set.ratio != model->ratio())
        throw_input_error(config.train_data, "patch set has ratio {} but the model has ratio {}",
                          train_set.ratio, model->ratio());
    LoaderOptions loader_options;
    loader_options.batch_size = config.batch_size;
    loader_options.sampler = parse_input_sampler(config.sampler);
    loader_options.augment = config.augment;
    loader_options.seed = config.seed;
    loader_options.shard_index = group.rank();
    loader_options.shard_count = group.world_size();
    PatchLoader loader(train_set, loader_options);

    std::optional<ValidationSet> val;
    if (!config.val_data.empty())
        val = make_validation_set(load_patch_set(config.val_data), config.val_patches,
                                  loader_options.sampler, config.seed);

    Adam adam(model->parameters(), AdamOptions{config.lr});
    int64_t step = 0;
    double best_val = std::numeric_limits<double>::infinity();
    double last_val = best_val;
    if (!state_info.is_null()) {
        adam.load_state(optimizer_state, state_info.at("adam"));
        step = state_info.at("step");
        // A run without validation stores its initial infinities, which JSON writes as null.
        for (auto [key, value] : {std::pair{"best_val_cd", &best_val}, {"last_val_cd", &last_val}})
            if (state_info.value(key, nlohmann::json()).is_number()) *value = state_info[key];
        loader.seek(state_info.at("loader_position"));
    }
    {
        ParamMap state;
        for (auto& [name, p] : model->parameters()) state["theta/" + name] = p;
        for (auto& [name, b] : model->buffers()) state["buffer/" + name] = b;
        for (auto& [name, t] : adam.state()) state["adam/" + name] = t;
        start_in_sync(
            group,
            {{"step", step}, {"loader_position", loader.position()}, {"adam_steps", adam.steps()}},
            state);
    }
    nlohmann::json extra = {{"train_config", config.to_json()}, {"sampler", config.sampler}};

    auto save_state = [&] {
        nlohmann::json info = {{"step", step},
                               {"adam", adam.state_info()},
                               {"best_val_cd", best_val},
                               {"last_val_cd", last_val},
                               {"loader_position", loader.position()},
                               {kRunConfigKey, comparable_config(config.to_json())}};
        save_training_state(state_file.string(), *model, adam.state(), info);
        nlohmann::json model_extra = extra;
        model_extra["step"] = step;
        model_extra["val_cd"] = last_val;
        save_checkpoint((fs::path(config.run_dir) / "model.pt").string(), *model, model_extra);
    };

    auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    std::optional<ProgressBar> progress;
    if (writes) progress.emplace(config.steps, "train");
    double loss_sum = 0;
    std::map<std::string, double> term_sums;  // of backbones whose loss has several terms
    int64_t loss_count = 0, first_step = step;
    int64_t saved_step = state_info.is_null() ? -1 : step;
    while (step < config.steps) {
        Batch batch = loader.next();
        adam.set_lr(learning_rate(config, step));
        model->update_buffers(batch.input, model->parameters());
        LossTerms terms = model->loss_terms(batch.input, batch.gt, model->parameters(), step);
        at::Tensor loss = sum_of(terms);
        ParamMap grads = gradients(loss, model->parameters());
        double loss_value = loss.item<double>();
        if (terms.size() > 1)
            for (const auto& [name, term] : terms) term_sums[name] += term.item<double>();
        bool stop =
            (stop_after_seconds > 0 && elapsed() > stop_after_seconds) || interrupt_requested();
        if (group.enabled()) all_reduce_step(group, grads, model->buffers(), loss_value, stop);
        adam.step(grads);
        ++step;
        if (!std::isfinite(loss_value))
            throw InternalError(fmt::format("train: loss became {} at step {}", loss_value, step));
        if (config.distributed.check_every > 0 && step % config.distributed.check_every == 0 &&
            !group.identical(model->parameters()))
            throw InternalError(
                fmt::format("train: the ranks' parameters differ after step {}", step));
        loss_sum += loss_value;
        ++loss_count;
        if (progress)
            progress->update(step, fmt::format("loss {:.3e} val {:.3e}", loss_value, last_val));
        if (writes && step % config.log_every == 0) {
            double seconds = elapsed();
            nlohmann::json line = {{"step", step},
                                   {"loss", loss_sum / loss_count},
                                   {"lr", adam.lr()},
                                   {"seconds", seconds},
                                   {"steps_per_second", (step - first_step) / seconds}};
            // This process's share of the batch only, when distributed.
            for (auto& [name, sum] : term_sums) {
                line["loss_" + name] = sum / loss_count;
                sum = 0;
            }
            append_log(log_file.string(), line);
            loss_sum = 0;
            loss_count = 0;
        }
        if (val && (step % config.val_every == 0 || step == config.steps || stop)) {
            last_val = distributed_validation_cd(*model, *val, group);
            bool improved = last_val < best_val;
            if (improved) best_val = last_val;
            if (improved && writes) {
                nlohmann::json best_extra = extra;
                best_extra["step"] = step;
                best_extra["val_cd"] = last_val;
                save_checkpoint((fs::path(config.run_dir) / "best.pt").string(), *model,
                                best_extra);
            }
            if (writes) {
                append_log(log_file.string(), {{"step", step},
                                               {"val_cd", last_val},
                                               {"best", improved},
                                               {"input_cd", val->input_cd},
                                               {"seconds", elapsed()}});
                spdlog::info("train: step {} val CD {:.4e} (best {:.4e}, input {:.4e})", step,
                             last_val, best_val, val->input_cd);
            }
        }
        if (writes && (step % config.checkpoint_every == 0 || step == config.steps || stop)) {
            save_state();
            saved_step = step;
        }
        if (stop) {
            if (writes)
                spdlog::info("train: {} at step {}; checkpoint saved, continue with --resume",
                             interrupt_requested() ? "interrupted" : "time limit reached", step);
            break;
        }
    }
    if (progress) progress->finish();
    // A fresh run that ends before its first step (steps = 0) still leaves its initial model.
    if (writes && saved_step != step) save_state();
    // Every rank returns only once rank 0's last checkpoint is on disk.
    group.barrier();
    return {step, best_val, last_val};
}

}  // namespace pumeta
