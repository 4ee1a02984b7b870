// One adaptation value from a model file's defaults and the user's overrides.
#include "pumeta/inference/adaptation.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "support/test_util.h"

namespace pumeta {
namespace {

const nlohmann::json kMeta = {{"inner_steps", 5}, {"inner_lr", 0.01}, {"adapt", {"up."}}};
const nlohmann::json kLearned = {{"up.weight", 0.2}, {"up.bias", 0.3}};

TEST(Adaptation, APlainModelDoesNotAdaptUntilAskedTo) {
    Adaptation stored = stored_adaptation(nullptr, nullptr);
    EXPECT_FALSE(stored.enabled());
    EXPECT_EQ(stored.inner.step_size, MetaOptions().inner_lr);
    Adaptation a = adaptation_for(stored, false, {});
    EXPECT_FALSE(a.enabled());
    AdaptationOverrides overrides;
    overrides.steps = 3;
    overrides.step_size = 0.05;
    a = adaptation_for(stored, false, overrides);
    EXPECT_TRUE(a.enabled());
    EXPECT_EQ(a.inner.steps, 3);
    EXPECT_EQ(a.inner.step_size, 0.05);
    EXPECT_EQ(a.unit, AdaptationUnit::kObject);
    EXPECT_FALSE(a.downsampler.has_value());
}

TEST(Adaptation, AMetaTrainedModelAdaptsWithItsStoredSettings) {
    Adaptation stored = stored_adaptation(kMeta, kLearned);
    Adaptation a = adaptation_for(stored, true, {});
    EXPECT_EQ(a.inner.steps, 5);
    EXPECT_EQ(a.inner.step_size, 0.01);
    EXPECT_TRUE(a.inner.adapts("up.weight"));
    EXPECT_FALSE(a.inner.adapts("feature.weight"));
    EXPECT_EQ(a.step_sizes.size(), 2u);
    EXPECT_EQ(a.to_json()["lr"], "learned");
    // Overrides replace each field; a step size replaces the learned ones.
    AdaptationOverrides overrides;
    overrides.steps = 0;
    EXPECT_FALSE(adaptation_for(stored, true, overrides).enabled());
    overrides = {};
    overrides.step_size = 0.1;
    overrides.unit = AdaptationUnit::kCloud;
    overrides.downsampler = InputSampler::kFps;
    a = adaptation_for(stored, true, overrides);
    EXPECT_TRUE(a.step_sizes.empty());
    EXPECT_EQ(a.inner.step_size, 0.1);
    EXPECT_EQ(a.unit, AdaptationUnit::kCloud);
    EXPECT_EQ(a.downsampler, InputSampler::kFps);
    EXPECT_EQ(a.to_json()["lr"], 0.1);
}

TEST(Adaptation, AdamTakesOneLearningRateNotLearnedStepSizes) {
    Adaptation stored = stored_adaptation(kMeta, kLearned);
    AdaptationOverrides overrides;
    overrides.optimizer = InnerOptimizer::kAdam;
    EXPECT_TRUE(test::throws_input_error([&] { adaptation_for(stored, true, overrides); },
                                         {"--tta-optimizer", "--tta-lr"}));
    overrides.step_size = 1e-3;
    Adaptation a = adaptation_for(stored, true, overrides);
    EXPECT_EQ(a.inner.optimizer, InnerOptimizer::kAdam);
    EXPECT_EQ(a.to_json()["optimizer"], "adam");
}

TEST(Adaptation, NamesParseOrNameTheProblem) {
    EXPECT_EQ(parse_adaptation_unit("patch", "--tta-unit"), AdaptationUnit::kPatch);
    EXPECT_EQ(to_string(AdaptationUnit::kCloud), "cloud");
    EXPECT_TRUE(test::throws_input_error([] { parse_adaptation_unit("oracle", "--tta-unit"); },
                                         {"--tta-unit", "oracle"}));
    EXPECT_EQ(parse_inner_optimizer("adam", "x"), InnerOptimizer::kAdam);
    EXPECT_TRUE(test::throws_input_error([] { parse_inner_optimizer("rmsprop", "opt"); },
                                         {"opt", "rmsprop"}));
}

}  // namespace
}  // namespace pumeta
