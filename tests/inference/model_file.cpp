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

}  // namespace
}  // namespace pumeta
