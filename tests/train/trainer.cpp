// Supervised training runs in-process on a tiny patch set: warm starts from a checkpoint of
// another ratio (init_from) and resuming.
#include "pumeta/train/trainer.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/nn/adam.h"
#include "pumeta/nn/gradients.h"
#include "pumeta/train/training_state.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;
using test::tiny_pugcn_config;

/// Two "meshes" of random points with six patch seeds each, for ratio `ratio`.
std::string write_patch_set(const test::TempDir& dir, int64_t ratio) {
    PatchSet set;
    set.ratio = ratio;
    set.patch_points = 16;
    set.points = uniform_random_points(400, 5);
    set.offsets = at::tensor({int64_t{0}, int64_t{200}, int64_t{400}});
    std::vector<int64_t> seeds;
    for (int64_t mesh = 0; mesh < 2; ++mesh)
        for (int64_t i = 0; i < 6; ++i) seeds.insert(seeds.end(), {mesh, i * 31});
    set.seeds = at::tensor(seeds).view({12, 2});
    set.ids = {"a", "b"};
    std::string path = dir.file("train-x" + std::to_string(ratio) + ".tensors");
    save_patch_set(path, set);
    return path;
}

TrainConfig tiny_config(const test::TempDir& dir, int64_t ratio, const std::string& run) {
    TrainConfig c;
    c.backbone = tiny_pugcn_config(ratio, 11);
    c.train_data = write_patch_set(dir, ratio);
    c.run_dir = dir.file(run);
    c.batch_size = 4;
    c.steps = 0;
    c.log_every = 1;
    return c;
}

TEST(Train, LogsEachTermOfALossWithSeveral) {
    test::TempDir dir;
    TrainConfig config = tiny_config(dir, 4, "dispu");
    config.backbone = test::tiny_dispu_config();
    config.backbone["repulsion_weight"] = 1.0;
    config.steps = 2;
    train(config, false);
    std::vector<nlohmann::json> lines = test::log_records(dir.file("dispu/log.jsonl"), "loss");
    ASSERT_EQ(lines.size(), 2u);
    for (const nlohmann::json& j : lines) {
        const double sum = j.at("loss_coarse").get<double>() + j.at("loss_fine").get<double>() +
                           j.at("loss_repulsion").get<double>();
        EXPECT_NEAR(j.at("loss").get<double>(), sum, 1e-5 * sum) << j.dump();
    }

    // A one-term loss logs only "loss".
    TrainConfig plain = tiny_config(dir, 4, "pugcn");
    plain.steps = 1;
    train(plain, false);
    std::vector<nlohmann::json> pugcn = test::log_records(dir.file("pugcn/log.jsonl"), "loss");
    ASSERT_EQ(pugcn.size(), 1u);
    for (const auto& [key, value] : pugcn[0].items()) EXPECT_NE(key.rfind("loss_", 0), 0u) << key;
}

TEST(Train, ACaughtSignalCheckpointsAndStopsAfterTheCurrentStep) {
    test::TempDir dir;
    TrainConfig config = tiny_config(dir, 4, "run");
    config.steps = 30;
    catch_interrupts();
    std::raise(SIGTERM);  // as if Ctrl-C came during the first step
    const int64_t stopped_at = train(config, /*resume=*/false).steps;
    reset_interrupts();
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
    EXPECT_EQ(stopped_at, 1);
    EXPECT_TRUE(fs::exists(config.run_dir + "/state.ckpt"));
    EXPECT_EQ(train(config, /*resume=*/true).steps, 30);  // the same config: no change to allow
}

TEST(Train, InitFromCopiesEveryTensorWhoseNameAndShapeMatch) {
    test::TempDir dir;
    auto source = make_backbone(tiny_pugcn_config(2, 99));
    save_checkpoint(dir.file("x2.pt"), *source);

    TrainConfig config = tiny_config(dir, 4, "x4");
    config.init_from = dir.file("x2.pt");
    train(config, false);
    LoadedCheckpoint warm = load_checkpoint(dir.file("x4/model.pt"));
    auto fresh = make_backbone(tiny_pugcn_config(4, 11));

    int64_t copied = 0, kept = 0;
    for (const auto& [name, t] : warm.backbone->parameters()) {
        const at::Tensor& from = source->parameters().at(name);
        if (from.sizes() == t.sizes()) {
            EXPECT_TRUE(at::equal(t, from)) << name;
            ++copied;
        } else {
            // The ratio-dependent layers keep the fresh model's initialisation.
            EXPECT_TRUE(at::equal(t, fresh->parameters().at(name))) << name;
            ++kept;
        }
    }
    EXPECT_GT(copied, 0);
    EXPECT_GT(kept, 0);
}

TEST(Train, InitFromAnotherBackboneIsAnInputErrorNamingTheFile) {
    test::TempDir dir;
    nlohmann::json other = {{"backbone", "dispu"}, {"ratio", 4}, {"preset", "compact"}};
    save_checkpoint(dir.file("dispu.pt"), *make_backbone(other));
    TrainConfig config = tiny_config(dir, 4, "x4");
    config.init_from = dir.file("dispu.pt");
    try {
        train(config, false);
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("dispu.pt"), std::string::npos) << e.what();
    }
}

TEST(Train, InitFromIsRecordedAndJsonRoundTrips) {
    test::TempDir dir;
    TrainConfig config = tiny_config(dir, 4, "x4");
    config.init_from = "models/pugcn-x4.pt";
    TrainConfig back = TrainConfig::from_json(config.to_json());
    EXPECT_EQ(back.init_from, config.init_from);
    EXPECT_EQ(back.to_json(), config.to_json());
}

TEST(Train, CiPresetTrainsThePaperWidthModelInSecondsAndResumes) {
    nlohmann::json j =
        nlohmann::json::parse(std::ifstream(test::source_dir() + "/configs/pugcn-x4-ci.json"));
    test::TempDir dir;
    // The preset's recipe on a miniature patch set of 256-point patches at 4x.
    PatchSet set;
    set.ratio = 4;
    set.patch_points = 256;
    set.points = uniform_random_points(2 * 1200, 7);
    set.offsets = at::tensor({int64_t{0}, int64_t{1200}, int64_t{2400}});
    set.seeds = at::tensor(std::vector<int64_t>{0, 0, 0, 600, 1, 0, 1, 600}).view({4, 2});
    set.ids = {"a", "b"};
    save_patch_set(dir.file("train.tensors"), set);
    j["train_data"] = dir.file("train.tensors");
    j["val_data"] = dir.file("train.tensors");
    j["run_dir"] = dir.file("ci");
    TrainConfig config = TrainConfig::from_json(j);
    TrainResult result = train(config, /*resume=*/false);
    EXPECT_EQ(result.steps, 20);
    EXPECT_TRUE(std::isfinite(result.best_val_cd));
    EXPECT_GT(result.best_val_cd, 0);
    LoadedCheckpoint trained = load_checkpoint(dir.file("ci/model.pt"));
    EXPECT_EQ(count_parameters(trained.backbone->parameters()), 75971);  // paper width
    config.steps = 30;
    EXPECT_EQ(train(config, /*resume=*/true, 0, {"steps"}).steps, 30);
}

TEST(Train, ResumeAfterAKillLogsEveryStepOnce) {
    test::TempDir dir;
    TrainConfig config = tiny_config(dir, 4, "run");
    config.steps = 6;
    config.checkpoint_every = 4;
    train(config, /*resume=*/false);
    // As if killed after step 6 with the last checkpoint at step 4: the state of step 4 and a
    // log that already holds steps 5 and 6 (and a line cut short by the kill).
    const std::string log = dir.file("run/log.jsonl");
    {
        config.steps = 4;
        test::TempDir other;
        TrainConfig four = config;
        four.run_dir = other.file("run");
        train(four, /*resume=*/false);
        fs::copy_file(four.run_dir + "/state.ckpt", config.run_dir + "/state.ckpt",
                      fs::copy_options::overwrite_existing);
    }
    std::ofstream(log, std::ios::app) << "{\"step\": 7, \"lo";
    config.steps = 6;
    train(config, /*resume=*/true, 0, {"steps"});
    std::vector<int64_t> steps;
    for (const nlohmann::json& line : test::log_records(log, "loss")) steps.push_back(line["step"]);
    EXPECT_EQ(steps, (std::vector<int64_t>{1, 2, 3, 4, 5, 6}));
}

// The helper the log tests read with: a writer (another rank, a run being killed) may be in
// the middle of the last line, which must be left out rather than parsed.
TEST(TestSupport, LogRecordsLeavesOutALastLineWithoutItsNewline) {
    test::TempDir dir;
    const std::string log = dir.file("log.jsonl");
    test::write_file(log,
                     "{\"step\": 1, \"loss\": 0.5}\n{\"step\": 1, \"val_cd\": 0.1}\n"
                     "{\"step\": 2, \"loss\": 0.4}\n{\"step\": 3, \"lo");
    std::vector<nlohmann::json> records = test::log_records(log, "loss");
    ASSERT_EQ(records.size(), 2u);
    EXPECT_EQ(records[0]["step"], 1);
    EXPECT_EQ(records[1]["step"], 2);
    EXPECT_EQ(test::log_records(log, "val_cd").size(), 1u);
}

TEST(Train, ResumeRefusesAChangedConfigUnlessTheFieldIsAllowed) {
    test::TempDir dir;
    TrainConfig config = tiny_config(dir, 4, "run");
    config.steps = 2;
    train(config, /*resume=*/false);
    TrainConfig changed = config;
    changed.steps = 4;
    changed.schedule.lr = config.schedule.lr * 2;
    EXPECT_TRUE(test::throws_input_error([&] { train(changed, /*resume=*/true); },
                                         {config.run_dir, "--resume with a changed config",
                                          "steps (2 -> 4)", "lr (", "--allow-change"}));
    EXPECT_TRUE(
        test::throws_input_error([&] { train(changed, /*resume=*/true, 0, {"steps"}); }, {"lr ("}));
    EXPECT_EQ(train(changed, /*resume=*/true, 0, {"steps", "lr"}).steps, 4);
    // The run directory and the process layout may differ between sessions.
    TrainConfig moved = changed;
    moved.steps = 5;
    fs::rename(config.run_dir, dir.file("moved"));
    moved.run_dir = dir.file("moved");
    EXPECT_EQ(train(moved, /*resume=*/true, 0, {"steps"}).steps, 5);
}

TEST(Train, ResumeComparesTheFieldsBothConfigsHave) {
    const nlohmann::json stored = {{"steps", 10}, {"meta", {{"inner_lr", 0.01}, {"retired", "x"}}}};
    // A field added since (written before it existed) or retired since is no change.
    EXPECT_TRUE(
        changed_fields(stored, {{"steps", 10.0}, {"meta", {{"inner_lr", 0.01}}}, {"new", 1}})
            .empty());
    EXPECT_EQ(changed_fields(stored, {{"steps", 20}, {"meta", {{"inner_lr", 0.02}}}}),
              (std::vector<std::string>{"meta.inner_lr", "steps"}));
    // The added ones are listed apart, so that the resume can name them.
    EXPECT_EQ(added_fields(
                  stored,
                  {{"steps", 10}, {"meta", {{"inner_lr", 0.01}, {"inner_steps", 5}}}, {"new", 1}}),
              (std::vector<std::string>{"meta.inner_steps", "new"}));
    EXPECT_TRUE(added_fields(stored, stored).empty());
}

TEST(Train, TwoTrainersCannotWriteOneRunDirectory) {
    test::TempDir dir;
    TrainConfig config = tiny_config(dir, 4, "run");
    config.steps = 1;
    fs::create_directories(config.run_dir);
    {
        RunLock held(config.run_dir);
        EXPECT_TRUE(test::throws_input_error([&] { train(config, /*resume=*/false); },
                                             {config.run_dir, "another trainer", "pid"}));
    }
    EXPECT_EQ(train(config, /*resume=*/false).steps, 1);
}

TEST(Train, ConfigTypeErrorsAreInputErrorsNamingTheField) {
    test::TempDir dir;
    nlohmann::json j = tiny_config(dir, 4, "x4").to_json();
    j["steps"] = "ten";
    try {
        TrainConfig::from_json(j);
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_STREQ(e.what(), "train config: 'steps' must be an integer, found \"ten\"");
    }
    j["steps"] = 3;
    j["distributed"] = {{"world_size", "two"}};
    EXPECT_THROW(TrainConfig::from_json(j), InputError);
}

/// What ToyAdversarial::training_terms saw at each call: the offset it was evaluated at and
/// the gradient of its summed terms there.
struct TermsCall {
    at::Tensor offset, gradient;
};
std::vector<TermsCall>& terms_calls() {
    static std::vector<TermsCall> calls;
    return calls;
}

/// A toy adversarial backbone: the generator shifts every input point by a learned offset and
/// repeats it r times; its auxiliary "discriminator" scores a cloud by w·mean + b and trains
/// with least-squares GAN losses.
class ToyAdversarial final : public Backbone {
  public:
    explicit ToyAdversarial(const nlohmann::json& config) : config_(config) {
        params_["offset"] = at::full({3}, 0.05).requires_grad_(true);
    }
    std::string name() const override { return "toy-adversarial"; }
    nlohmann::json config() const override { return config_; }
    int64_t ratio() const override { return config_.at("ratio"); }
    int64_t patch_size() const override { return 16; }
    at::Tensor upsample(const at::Tensor& x, const ParamMap& params) const override {
        return (x + params.at("offset")).repeat({1, ratio(), 1});
    }
    at::Tensor loss(const at::Tensor& x, const at::Tensor& y, const ParamMap& params,
                    int64_t) const override {
        return (upsample(x, params).mean(1) - y.mean(1)).square().sum(1).mean();
    }
    at::Tensor downsample(const at::Tensor& dense, uint64_t) const override {
        return dense.slice(1, 0, dense.size(1) / ratio());
    }
    ParamMap make_auxiliary(uint64_t seed) const override {
        return {{"w", at::full({3}, 0.1 + 0.01 * static_cast<double>(seed)).requires_grad_(true)},
                {"b", at::zeros({}).requires_grad_(true)}};
    }
    LossTerms training_terms(const at::Tensor& x, const at::Tensor& y, const ParamMap& params,
                             const ParamMap& aux, int64_t step) const override {
        record_call(x, y, params, aux, step);
        return terms_at(x, y, params, aux, step);
    }
    at::Tensor auxiliary_loss(const at::Tensor& x, const at::Tensor& y, const ParamMap& params,
                              const ParamMap& aux, int64_t) const override {
        at::Tensor fake;
        {
            at::NoGradGuard no_grad;
            fake = upsample(x, params);
        }
        return (score(y, aux) - 1).square().mean() + score(fake, aux).square().mean();
    }
    double auxiliary_lr(int64_t) const override { return 0.01; }

  private:
    LossTerms terms_at(const at::Tensor& x, const at::Tensor& y, const ParamMap& params,
                       const ParamMap& aux, int64_t step) const {
        LossTerms terms = loss_terms(x, y, params, step);
        terms.emplace_back("adversarial", (score(upsample(x, params), aux) - 1).square().mean());
        return terms;
    }
    void record_call(const at::Tensor& x, const at::Tensor& y, const ParamMap& params,
                     const ParamMap& aux, int64_t step) const {
        ParamMap copy = {{"offset", params.at("offset").detach().clone().requires_grad_(true)}};
        ParamMap fixed_aux;
        for (const auto& [name, t] : aux) fixed_aux[name] = t.detach();
        at::Tensor total = sum_of(terms_at(x, y, copy, fixed_aux, step));
        terms_calls().push_back({copy.at("offset").detach(), gradients(total, copy).at("offset")});
    }
    static at::Tensor score(const at::Tensor& cloud, const ParamMap& aux) {
        return at::matmul(cloud.mean(1), aux.at("w")) + aux.at("b");
    }
    nlohmann::json config_;
};

/// Registers ToyAdversarial once per process (the tests may run in one).
void register_toy_adversarial() {
    static const bool registered = [] {
        register_backbone("toy-adversarial", [](const nlohmann::json& config) {
            return std::make_unique<ToyAdversarial>(config);
        });
        return true;
    }();
    (void)registered;
}

/// A run of ToyAdversarial (registered) in `dir/name`: `steps` steps at learning rate 0.01.
TrainConfig adversarial_config(const test::TempDir& dir, const std::string& name, int64_t steps) {
    register_toy_adversarial();
    TrainConfig config = tiny_config(dir, 4, name);
    config.backbone = {{"backbone", "toy-adversarial"}, {"ratio", 4}};
    config.steps = steps;
    config.schedule.lr = 0.01;
    return config;
}

TEST(Train, AnAuxiliaryNetworkTrainsWithItsOwnLossAndResumesOutsideTheModel) {
    test::TempDir dir;
    TrainConfig config = adversarial_config(dir, "straight", 4);
    train(config, false);
    // The log has the adversarial term and the auxiliary loss of every step.
    std::vector<nlohmann::json> lines = test::log_records(dir.file("straight/log.jsonl"), "loss");
    ASSERT_EQ(lines.size(), 4u);
    for (const nlohmann::json& j : lines) {
        EXPECT_TRUE(j.contains("loss_adversarial")) << j.dump();
        EXPECT_GT(j.at("auxiliary_loss").get<double>(), 0.0) << j.dump();
    }
    // The discriminator trained (its w left the initial 0.11) and lives in the run state only.
    TrainingState state = load_training_state(dir.file("straight/state.ckpt"));
    ASSERT_TRUE(state.optimizer.count("aux/w"));
    EXPECT_FALSE(at::allclose(state.optimizer.at("aux/w"), at::full({3}, 0.11)));
    LoadedCheckpoint shipped = load_checkpoint(dir.file("straight/model.pt"));
    EXPECT_EQ(shipped.backbone->parameters().size(), 1u);
    EXPECT_EQ(shipped.extra.dump().find("aux"), std::string::npos);

    // Two steps, then two more after a resume: the same generator and discriminator.
    config.run_dir = dir.file("resumed");
    config.steps = 2;
    train(config, false);
    config.steps = 4;
    train(config, true, 0, {"steps"});
    TrainingState resumed = load_training_state(dir.file("resumed/state.ckpt"));
    for (const std::string name : {"aux/w", "aux/b"})
        EXPECT_TRUE(at::equal(resumed.optimizer.at(name), state.optimizer.at(name))) << name;
    EXPECT_TRUE(at::equal(param(resumed.model->parameters(), "offset"),
                          param(state.model->parameters(), "offset")));
}

TEST(Train, TheAuxiliaryLearningRateDecaysWithTheRunsSchedule) {
    test::TempDir dir;
    TrainConfig config = adversarial_config(dir, "decayed", 3);
    config.schedule.rate = 0.5;
    config.schedule.steps = 1;
    train(config, false);
    // The last step (index 2) ran at 0.5² of both initial rates: the backbone's 0.01 and the
    // auxiliary network's 0.01 (ToyAdversarial::auxiliary_lr).
    TrainingState state = load_training_state(dir.file("decayed/state.ckpt"));
    EXPECT_DOUBLE_EQ(state.info.at("adam").at("lr").get<double>(), 0.0025);
    EXPECT_DOUBLE_EQ(state.info.at("aux_adam").at("lr").get<double>(), 0.0025);
}

TEST(Train, UpdatesPerBatchStepsTheBackboneThatOftenPerAuxiliaryStep) {
    test::TempDir dir;
    TrainConfig config = adversarial_config(dir, "twice", 3);
    config.updates_per_batch = 2;
    terms_calls().clear();
    train(config, false);
    // PU-GAN's rhythm: two generator steps per batch, one discriminator step.
    TrainingState state = load_training_state(dir.file("twice/state.ckpt"));
    EXPECT_EQ(state.info.at("adam").at("step").get<int64_t>(), 6);
    EXPECT_EQ(state.info.at("aux_adam").at("step").get<int64_t>(), 3);

    // Each update takes a fresh gradient at the weights the previous one left: replaying
    // Adam on the gradients the toy saw gives the trained weights (a trainer that applied
    // one gradient twice, or evaluated both at the batch's first weights, would not).
    const std::vector<TermsCall> calls = terms_calls();
    ASSERT_EQ(calls.size(), 6u);
    ParamMap replay = {{"offset", calls.front().offset.clone()}};
    Adam adam(replay, AdamOptions{});
    for (size_t i = 0; i < calls.size(); ++i) {
        adam.set_lr(config.schedule.at(static_cast<int64_t>(i / 2)));
        EXPECT_TRUE(at::allclose(replay.at("offset"), calls[i].offset, 1e-5, 1e-7));
        adam.step({{"offset", calls[i].gradient}});
    }
    EXPECT_TRUE(
        at::allclose(param(state.model->parameters(), "offset"), replay.at("offset"), 1e-5, 1e-7));

    // The generator ends elsewhere than with one update per batch.
    config.updates_per_batch = 1;
    config.run_dir = dir.file("once");
    train(config, false);
    TrainingState once = load_training_state(dir.file("once/state.ckpt"));
    EXPECT_FALSE(at::equal(param(once.model->parameters(), "offset"),
                           param(state.model->parameters(), "offset")));

    nlohmann::json j = config.to_json();
    j["updates_per_batch"] = 0;
    EXPECT_TRUE(test::throws_input_error([&] { TrainConfig::from_json(j); },
                                         {"train config", "'updates_per_batch' must be >= 1"}));
}

}  // namespace
}  // namespace pumeta
