// The meta-training config, and validation's treatment of a diverged inner loop. Meta-training
// itself runs in tests/distributed/data_parallel.cpp (one and two processes) and
// tests/eval/reproduce.cpp (the CLI end to end).
#include "pumeta/meta/meta_trainer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/models/metapu.h"
#include "support/hdf5_files.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

nlohmann::json minimal() {
    return {{"init", "models/pugcn-x4.pt"},
            {"train_data", "data/dataset/train-x4.tensors"},
            {"run_dir", "runs/x"}};
}

std::string error_of(const nlohmann::json& j) {
    try {
        MetaTrainConfig::from_json(j);
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

/// Writes 8 sheet patches (16 -> 64 points) as train and validation data and `model` as the
/// initial checkpoint into `dir`; returns the config fields that point at them.
nlohmann::json sheet_tasks(const test::TempDir& dir, const nlohmann::json& model) {
    const at::Tensor gt = test::sheet(8, 64, 5);
    const std::string h5 = dir.file("patches.h5");
    test::write_hdf5(h5,
                     {{"poisson_16", gt.slice(1, 0, 16).contiguous(), {}}, {"poisson_64", gt, {}}});
    save_checkpoint(dir.file("init.pt"), *make_backbone(model));
    return {{"init", dir.file("init.pt")},
            {"train_data", h5},
            {"val_data", h5},
            {"data_input_key", "poisson_16"},
            {"data_gt_key", "poisson_64"}};
}

TEST(MetaTrainConfig, ReadsNestedMetaOptionsAndRoundTrips) {
    nlohmann::json j = minimal();
    j["meta"] = {
        {"inner_steps", 3}, {"inner_lr", 0.01}, {"learn_inner_lr", true}, {"adapt", {"out."}}};
    j["tasks_per_batch"] = 4;
    j["comment"] = "free text";
    MetaTrainConfig c = MetaTrainConfig::from_json(j);
    EXPECT_EQ(c.meta.inner_steps, 3);
    EXPECT_DOUBLE_EQ(c.meta.inner_lr, 0.01);
    EXPECT_TRUE(c.meta.learn_inner_lr);
    EXPECT_FALSE(c.meta.first_order);
    EXPECT_TRUE(c.meta.inner_loop().adapts("out.fc0.weight"));
    EXPECT_FALSE(c.meta.inner_loop().adapts("head.weight"));
    EXPECT_EQ(c.tasks_per_batch, 4);
    EXPECT_EQ(c.steps, MetaTrainConfig().steps);
    nlohmann::json written = c.to_json();
    EXPECT_FALSE(written.contains("comment"));
    EXPECT_EQ(MetaTrainConfig::from_json(written).to_json(), written);
}

TEST(MetaTrainConfig, MissingUnknownOrMistypedFieldsAreInputErrors) {
    for (const char* field : {"init", "train_data", "run_dir"}) {
        nlohmann::json j = minimal();
        j.erase(field);
        EXPECT_EQ(error_of(j), fmt::format("meta-train config: '{}' is required", field));
    }
    nlohmann::json j = minimal();
    j["outer_lr"] = "1e-4";
    EXPECT_EQ(error_of(j), "meta-train config: 'outer_lr' must be a number, found \"1e-4\"");
    j = minimal();
    j["tasks"] = 8;
    EXPECT_EQ(error_of(j), "meta-train config: unknown field 'tasks'");
    j = minimal();
    j["meta"] = {{"inner_step", 5}};
    EXPECT_EQ(error_of(j), "meta config: unknown field 'inner_step'");
    j["meta"] = {{"first_order", "yes"}};
    EXPECT_EQ(error_of(j), "meta config: 'first_order' must be true or false, found \"yes\"");
    j["meta"] = {{"inner_lr", -1}};
    EXPECT_EQ(error_of(j), "meta config: inner_lr must be >= 0");
    j = minimal();
    j["tasks_per_batch"] = 3;
    j["distributed"] = {{"world_size", 2}};
    EXPECT_EQ(error_of(j),
              "meta-train config: tasks_per_batch 3 does not split evenly over 2 processes");
}

// A step size that blows every validation task up: validation scores those tasks unadapted
// (as test-time adaptation does), says so, and logs finite numbers, instead of scoring
// whatever NaN weights select.
TEST(MetaTrainValidation, DivergedTasksAreScoredUnadapted) {
    test::TempDir dir;
    nlohmann::json config = sheet_tasks(dir, test::tiny_pugcn_config(4, 11));
    config.update({{"run_dir", dir.file("meta")},
                   {"meta", {{"inner_steps", 2}, {"inner_lr", 1e9}}},
                   {"tasks_per_batch", 4},
                   {"val_tasks", 4},
                   {"steps", 0},
                   {"log_every", 1}});
    test::write_file(dir.file("meta.json"), config.dump());
    auto r = test::run_cli({"--threads", "1", "meta-train", "--config", dir.file("meta.json")});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("adaptation diverged on 4 of 4 tasks"), std::string::npos) << r.err;
    std::vector<nlohmann::json> entries =
        test::log_records(dir.file("meta/log.jsonl"), "val_cd_after");
    for (const nlohmann::json& entry : entries) {
        EXPECT_EQ(entry["val_cd_after"], entry["val_cd_before"]) << entry;
        EXPECT_EQ(entry["val_inner_after"], entry["val_inner_before"]) << entry;
    }
    EXPECT_EQ(entries.size(), 1u);
}

// Tasks at several ratios of one any-ratio model: every validation task is at a listed ratio
// (X from the GT patch), the ratio models share the meta-trained weights (so the score before
// adaptation moves with the outer steps), and a ratio the model does not serve is an input
// error naming the model.
TEST(MetaTrainTaskRatios, TasksAtSeveralRatiosTrainOneSetOfWeights) {
    test::TempDir dir;
    nlohmann::json model = metapu_small_config();
    model["reconstruction"] = "chamfer";
    nlohmann::json config = sheet_tasks(dir, model);
    config.update({{"meta", {{"inner_steps", 1}, {"inner_lr", 1e-3}}},
                   {"outer_lr", 1e-2},
                   {"tasks_per_batch", 2},
                   {"val_tasks", 4},
                   {"steps", 2},
                   {"val_every", 1},
                   {"log_every", 1}});
    auto run = [&](const std::string& name, const nlohmann::json& ratios) {
        nlohmann::json c = config;
        c["run_dir"] = dir.file(name);
        c["task_ratios"] = ratios;
        test::write_file(dir.file(name + ".json"), c.dump());
        return test::run_cli(
            {"--threads", "1", "meta-train", "--config", dir.file(name + ".json")});
    };
    auto before = [&](const std::string& name) {
        std::vector<double> cds;
        for (const nlohmann::json& entry :
             test::log_records(dir.file(name + "/log.jsonl"), "val_cd_after"))
            cds.push_back(entry["val_cd_before"]);
        return cds;
    };
    auto r = run("x2x3", {2, 3});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::vector<double> mixed = before("x2x3");
    ASSERT_EQ(mixed.size(), 3u);
    for (double cd : mixed) EXPECT_TRUE(std::isfinite(cd) && cd > 0) << cd;
    EXPECT_NE(mixed[0], mixed[2]);  // the ratio models see the outer steps' weights

    r = run("x2", {2});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run("x3", {3});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // Step 0 (same weights): half the mixed run's tasks are at 2x, half at 3x.
    const double x2 = before("x2")[0], x3 = before("x3")[0];
    EXPECT_NE(x2, x3);
    EXPECT_NE(mixed[0], x2);
    EXPECT_NE(mixed[0], x3);

    r = run("x17", {2, 17});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("'task_ratios': the metapu model of '" + dir.file("init.pt") +
                         "' does not serve 17x"),
              std::string::npos)
        << r.err;
}

}  // namespace
}  // namespace pumeta
