// Which shipped model `pumeta upsample` picks when no --model is given, and loading a model
// at another ratio.
#include "pumeta/inference/model_file.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>

#include "pumeta/models/checkpoint.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

TEST(DefaultModel, ANativeModelForTheRatioElseAPowerOfAShippedOne) {
    test::TempDir dir;
    test::write_file(dir.file("defaults.json"), R"({"family": "pugcn"})");
    test::write_file(dir.file("pugcn-x4.pt"), "x");
    setenv("PUMETA_MODELS", dir.path().c_str(), 1);
    auto name = [](int64_t ratio) { return fs::path(default_model_for_ratio(ratio)).filename(); };
    EXPECT_EQ(name(0), "pugcn-x4.pt");
    EXPECT_EQ(name(4), "pugcn-x4.pt");
    EXPECT_EQ(name(16), "pugcn-x4.pt");
    EXPECT_EQ(name(8), "pugcn-x4.pt");  // no 8x model: the 4x one, which then rejects 8
    test::write_file(dir.file("pugcn-x8.pt"), "x");
    EXPECT_EQ(name(8), "pugcn-x8.pt");
    EXPECT_EQ(name(64), "pugcn-x8.pt");
    EXPECT_EQ(name(16), "pugcn-x4.pt");
    // The family is data: another one, or none, is the file's business.
    test::write_file(dir.file("defaults.json"), R"({"family": "dispu"})");
    test::write_file(dir.file("dispu-x4.pt"), "x");
    EXPECT_EQ(name(16), "dispu-x4.pt");
    test::write_file(dir.file("defaults.json"), R"({"models": []})");
    EXPECT_TRUE(test::throws_input_error([] { default_model_for_ratio(4); }, {"defaults.json"}));
    unsetenv("PUMETA_MODELS");
}

TEST(LoadInferenceModel, PuDenseWeightsServeAnyRatioWithPatchesOfTheTrainedOutputSize) {
    test::TempDir dir;
    nlohmann::json config = {
        {"backbone", "pudense"}, {"ratio", 8},       {"channels", {4, 4, 8, 8, 8}},
        {"resolution", 4},       {"patch_size", 32}, {"seed", 3}};
    std::unique_ptr<Backbone> trained = make_backbone(config);
    std::string file = dir.file("pudense-x8.pt");
    save_checkpoint(file, *trained);

    InferenceModel own = load_inference_model(file);
    EXPECT_EQ(own.backbone->ratio(), 8);
    EXPECT_EQ(load_inference_model(file, 8).backbone->patch_size(), 32);
    for (auto [ratio, patch] : {std::pair{4, 64}, std::pair{16, 16}, std::pair{3, 85}}) {
        InferenceModel model = load_inference_model(file, ratio);
        EXPECT_EQ(model.backbone->ratio(), ratio);
        // 32 points x 8 = 256 output points per patch, as trained (85 x 3 rounds 256 / 3).
        EXPECT_EQ(model.backbone->patch_size(), patch);
        for (const auto& [name, p] : trained->parameters())
            EXPECT_TRUE(at::equal(param(model.backbone->parameters(), name), p)) << name;
        for (const auto& [name, b] : trained->buffers())
            EXPECT_TRUE(at::equal(param(model.backbone->buffers(), name), b)) << name;
        at::Tensor x = at::rand({1, patch, 3}, at::TensorOptions().dtype(at::kFloat)) * 2 - 1;
        EXPECT_EQ(model.backbone->upsample(x).size(1), ratio * patch);
    }
}

TEST(LoadInferenceModel, RatioBoundWeightsKeepTheirRatio) {
    test::TempDir dir;
    std::unique_ptr<Backbone> pugcn = make_backbone(test::tiny_pugcn_config(4, 1));
    EXPECT_TRUE(pugcn->config_for_ratio(8).is_null());
    std::string file = dir.file("pugcn-x4.pt");
    save_checkpoint(file, *pugcn);
    // 16x = the 4x model twice (the pipeline's business): the model stays 4x.
    EXPECT_EQ(load_inference_model(file, 16).backbone->ratio(), 4);
    EXPECT_TRUE(make_backbone(test::tiny_dispu_config(4))->config_for_ratio(8).is_null());
}

TEST(Serve, DecidesTheRatioAndTheModelThatServesIt) {
    test::TempDir dir;
    save_checkpoint(dir.file("pugcn-x4.pt"), *make_backbone(test::tiny_pugcn_config(4, 1)));
    save_checkpoint(dir.file("pugcn-x8.pt"), *make_backbone(test::tiny_pugcn_config(8, 2)));
    test::write_file(dir.file("defaults.json"), R"({"family": "pugcn"})");
    setenv("PUMETA_MODELS", dir.path().c_str(), 1);
    // No model and no ratio: the shipped default at its own ratio.
    ServedModel served = serve("", 0);
    EXPECT_EQ(served.ratio, kDefaultRatio);
    EXPECT_EQ(served.model.backbone->ratio(), 4);
    // No model: the shipped one for the ratio (8x native, 16x the 4x model twice).
    EXPECT_EQ(serve("", 8).model.backbone->ratio(), 8);
    served = serve("", 16);
    EXPECT_EQ(served.ratio, 16);
    EXPECT_EQ(served.model.backbone->ratio(), 4);
    // A given model: its own ratio, or a power of it; anything else names both ratios.
    EXPECT_EQ(serve(dir.file("pugcn-x8.pt"), 0).ratio, 8);
    EXPECT_EQ(serve(dir.file("pugcn-x8.pt"), 64).ratio, 64);
    EXPECT_TRUE(test::throws_input_error([&] { serve(dir.file("pugcn-x8.pt"), 4); },
                                         {"ratio 4", "model's ratio 8"}));
    unsetenv("PUMETA_MODELS");
}

TEST(Serve, AnyRatioWeightsAreRebuiltAtTheRatio) {
    test::TempDir dir;
    save_checkpoint(dir.file("pudense-x8.pt"), *make_backbone({{"backbone", "pudense"},
                                                               {"ratio", 8},
                                                               {"channels", {4, 4, 8, 8, 8}},
                                                               {"resolution", 4},
                                                               {"patch_size", 32},
                                                               {"seed", 3}}));
    ServedModel served = serve(dir.file("pudense-x8.pt"), 5);
    EXPECT_EQ(served.ratio, 5);
    EXPECT_EQ(served.model.backbone->ratio(), 5);
}

TEST(LoadInferenceModel, AMetaTrainedFileCarriesItsAdaptationDefaults) {
    test::TempDir dir;
    std::unique_ptr<Backbone> model = make_backbone(test::tiny_pugcn_config(4, 1));
    save_checkpoint(dir.file("plain.pt"), *model);
    InferenceModel plain = load_inference_model(dir.file("plain.pt"));
    EXPECT_FALSE(plain.meta_trained);
    EXPECT_FALSE(plain.adaptation.enabled());
    // A file written before the meta options lost their investigation fields.
    save_checkpoint(dir.file("meta.pt"), *model,
                    {{"meta",
                      {{"inner_steps", 3},
                       {"inner_lr", 0.02},
                       {"outer_objective", "loss"},
                       {"inner_optimizer", "sgd"}}},
                     {"step_sizes", {{"feature.conv.weight", 0.5}}}});
    InferenceModel meta = load_inference_model(dir.file("meta.pt"));
    EXPECT_TRUE(meta.meta_trained);
    EXPECT_EQ(meta.adaptation.inner.steps, 3);
    EXPECT_EQ(meta.adaptation.inner.step_size, 0.02);
    ASSERT_EQ(meta.adaptation.step_sizes.size(), 1u);
    EXPECT_EQ(meta.adaptation.step_sizes.begin()->second.item<double>(), 0.5);
}

}  // namespace
}  // namespace pumeta
