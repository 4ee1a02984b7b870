// MPU: parameter counts against the original's layer list, every level count (1-4 levels:
// output sizes, config_for_ratio, the residual and point-major copies), the skip weights
// against a hand computation, the test-time crops against brute force, the loss and its
// threshold, the curriculum and its frozen levels, and serving any ratio from one file.
#include "pumeta/models/mpu.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "pumeta/inference/model_file.h"
#include "pumeta/inference/upsample.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/gradients.h"
#include "support/test_util.h"

namespace pumeta {

namespace {

// A small 4-level MPU (16×) whose levels crop: 16-point patches.
nlohmann::json small_config(int64_t ratio = 16) {
    nlohmann::json config = mpu_small_config();
    config["levels"] = 4;
    config["ratio"] = ratio;
    config["skip_neighbors"] = 5;
    return config;
}

Mpu make(const nlohmann::json& config) { return Mpu(MpuOptions::from_json(config)); }

// One level's trainable variables from the original's layer list (dense_interlevelplus.py):
// layer0, four dense blocks (three convolutions each, prep convolutions before blocks 2-4),
// up_layer1 on [264 features, 1-D code], up_layer2, fc_layer1, fc_layer2; all with biases.
int64_t original_level_parameters() {
    auto conv = [](int64_t in, int64_t out) { return in * out + out; };
    int64_t total = conv(3, 24);
    int64_t channels = 24;
    for (int64_t b = 0; b < 4; ++b) {
        int64_t in = 24;
        if (b > 0) total += conv(channels, 24);  // layer<b>_prep: 2·growth outputs
        total += conv(2 * in, 12) + conv(12 + in, 12) + conv(24 + in, 12);
        channels = (b == 0 ? 24 : channels) + 36 + in;
    }
    EXPECT_EQ(channels, 264);
    return total + conv(channels + 1, 128) + conv(128, 128) + conv(128, 64) + conv(64, 3);
}

int64_t count_with_prefix(const ParamMap& params, const std::string& prefix) {
    int64_t total = 0;
    for (const auto& [name, p] : params)
        if (name.rfind(prefix, 0) == 0) total += p.numel();
    return total;
}

// Zero coordinate heads: every level returns its input points, each copied twice.
void zero_heads(Backbone& model) {
    at::NoGradGuard no_grad;
    for (auto& [name, p] : model.parameters())
        if (name.find(".fc2.") != std::string::npos) p.zero_();
}

}  // namespace

TEST(Mpu, PaperWidthHas76027ParametersPerLevelAnd304108InAll) {
    EXPECT_EQ(original_level_parameters(), 76027);
    Mpu model = make({{"backbone", "mpu"}});
    EXPECT_EQ(model.options().levels, 4);
    EXPECT_EQ(model.ratio(), 16);
    EXPECT_EQ(model.options().k, 32);
    EXPECT_EQ(count_parameters(model.parameters()), 304108);
    for (int64_t level = 1; level <= 4; ++level)
        EXPECT_EQ(count_with_prefix(model.parameters(), "level" + std::to_string(level) + "."),
                  76027)
            << "level " << level;
    EXPECT_EQ(mpu_level_parameters(model.options()), 76027);
    // A 4× model of the same weights keeps every level (the file serves 2×-16×).
    Mpu x4 = make(model.config_for_ratio(4));
    EXPECT_EQ(count_parameters(x4.parameters()), 304108);
    EXPECT_EQ(x4.active_levels(), 2);
}

TEST(Mpu, OptionsValidateTheRatioAgainstTheLevels) {
    EXPECT_EQ(make({{"backbone", "mpu"}, {"levels", 3}}).ratio(), 8);
    EXPECT_EQ(make({{"backbone", "mpu"}, {"ratio", 4}}).active_levels(), 2);
    EXPECT_TRUE(test::throws_input_error(
        [] {
            make({{"backbone", "mpu"}, {"ratio", 6}});
        },
        {"mpu config", "'ratio'"}));
    EXPECT_TRUE(test::throws_input_error(
        [] {
            make({{"backbone", "mpu"}, {"levels", 2}, {"ratio", 8}});
        },
        {"'ratio'"}));
    EXPECT_TRUE(test::throws_input_error(
        [] {
            make({{"backbone", "mpu"}, {"width", 3}});
        },
        {"unknown field 'width'"}));
    EXPECT_TRUE(test::throws_input_error(
        [] {
            make({{"backbone", "mpu"}, {"preset", "x"}});
        },
        {"unknown preset"}));
    Mpu model = make(small_config());
    EXPECT_EQ(make(model.config()).config(), model.config());
}

TEST(Mpu, EveryLevelCountServesItsRatioFromTheSameWeights) {
    Mpu model = make(small_config());
    for (int64_t r : {1, 3, 6, 32, 64}) EXPECT_TRUE(model.config_for_ratio(r).is_null()) << r;
    at::Tensor x = test::sheet(2, 16, 1);
    for (int64_t levels = 1; levels <= 4; ++levels) {
        const int64_t r = int64_t(1) << levels;
        nlohmann::json config = model.config_for_ratio(r);
        ASSERT_FALSE(config.is_null()) << r;
        auto at_ratio = make_backbone(config);
        EXPECT_EQ(at_ratio->ratio(), r);
        ASSERT_EQ(at_ratio->parameters().size(), model.parameters().size());
        for (const auto& [name, p] : at_ratio->parameters())
            EXPECT_TRUE(p.equal(model.parameters().at(name))) << name;
        at::NoGradGuard no_grad;
        for (int64_t n : {16, 9}) {
            at::Tensor y = at_ratio->upsample(x.slice(1, 0, n));
            EXPECT_EQ(y.sizes(), (std::vector<int64_t>{2, r * n, 3})) << r << "x, " << n;
            EXPECT_TRUE(y.isfinite().all().item<bool>());
        }
        // X↓ for adaptation is taken at the served ratio.
        EXPECT_EQ(at_ratio->downsample(test::sheet(1, 64, 2), 3).size(1), 64 / r);
    }
}

TEST(Mpu, ZeroHeadsCopyTheInputPointMajorAtEveryLevelCount) {
    for (int64_t levels = 1; levels <= 4; ++levels) {
        const int64_t r = int64_t(1) << levels;
        // 2 points: no level's input exceeds the 16-point patch, so no crops: exact copies.
        Mpu model = make(small_config(r));
        zero_heads(model);
        at::NoGradGuard no_grad;
        at::Tensor x = test::sheet(1, 2, 4);
        at::Tensor expected = x.repeat_interleave(r, 1);
        EXPECT_TRUE(at::allclose(model.upsample(x), expected, 1e-5, 1e-5)) << r << "x";
        // With crops (16 points: levels 2-4 cropped and merged by FPS) the outputs are still
        // input points.
        at::Tensor dense_x = test::sheet(1, 16, 5);
        at::Tensor y = model.upsample(dense_x)[0];
        at::Tensor gap = (y.unsqueeze(1) - dense_x[0].unsqueeze(0)).norm(2, -1);  // [16r,16]
        EXPECT_LT(std::get<0>(gap.min(1)).max().item<double>(), 1e-5) << r << "x";
    }
}

TEST(Mpu, SkipWeightsMatchAHandComputation) {
    // One sample, two points, two previous-level neighbours each, 1-D features.
    at::Tensor xyz = at::tensor({0.0, 0.0, 0.0, 1.0, 0.0, 0.0}).view({1, 2, 3});
    at::Tensor f = at::tensor({0.0, 1.0}).view({1, 2, 1});
    at::Tensor nx =
        at::tensor({0.1, 0.0, 0.0, 0.3, 0.0, 0.0, 1.0, 0.0, 0.0, 1.2, 0.0, 0.0}).view({1, 2, 2, 3});
    at::Tensor nf = at::tensor({0.5, 1.0, 1.0, 3.0}).view({1, 2, 2, 1});
    at::Tensor w = mpu_skip_weights(xyz.to(at::kDouble), f.to(at::kDouble), nx.to(at::kDouble),
                                    nf.to(at::kDouble));
    // d_s = {0.01, 0.09; 0, 0.04}, h_s = (0.01 + 0) / 2; d_f = {0.25, 1; 0, 4}, h_f = 0.125.
    const double ds[2][2] = {{0.01, 0.09}, {0.0, 0.04}}, df[2][2] = {{0.25, 1.0}, {0.0, 4.0}};
    const double hs = 0.005, hf = 0.125;
    for (int i = 0; i < 2; ++i) {
        double raw[2], sum = 0;
        for (int j = 0; j < 2; ++j) {
            raw[j] = std::exp(-df[i][j] / (hf / 2)) * std::exp(-ds[i][j] / (hs / 2));
            sum += raw[j] + 1e-5;
        }
        for (int j = 0; j < 2; ++j)
            EXPECT_NEAR(w[0][i][j].item<double>(), raw[j] / sum, 1e-9) << i << "," << j;
    }
    // No gradient flows through the weights, and h = 0 (every nearest neighbour coincident)
    // stays finite.
    at::Tensor fg = f.clone().requires_grad_(true);
    EXPECT_FALSE(mpu_skip_weights(xyz, fg, nx, nf).requires_grad());
    at::Tensor same = xyz.unsqueeze(2).expand({1, 2, 2, 3}).contiguous();
    at::Tensor w0 = mpu_skip_weights(xyz, f, same, f.unsqueeze(2).expand({1, 2, 2, 1}));
    EXPECT_TRUE(w0.isfinite().all().item<bool>());
    EXPECT_NEAR(w0.sum(2)[0][0].item<double>(), 1.0, 1e-4);
}

TEST(Mpu, TestCropsAreTheNearestPointsOfFpsSeedsWithoutOutliers) {
    at::Tensor points = test::sheet(1, 64, 6)[0].clone();
    points[10] = at::tensor({30.0, 30.0, 30.0});  // an outlier
    at::Tensor crops = mpu_test_crops(points, 16);
    EXPECT_EQ(crops.sizes(), (std::vector<int64_t>{int64_t(64.0 / 16 * 5), 16}));
    EXPECT_FALSE((crops == 10).any().item<bool>());
    for (int64_t c = 0; c < crops.size(0); ++c) {
        at::Tensor crop = crops[c];
        EXPECT_EQ(std::get<0>(at::_unique(crop)).numel(), 16) << "crop " << c;
        // Brute force: no kept point outside the crop is nearer its seed (the crop's first
        // index) than the crop's farthest member.
        at::Tensor seed = points[crop[0].item<int64_t>()];
        at::Tensor d = (points - seed).pow(2).sum(1);
        d[10] = INFINITY;
        at::Tensor inside = at::zeros({64}, at::kBool).index_fill_(0, crop, true);
        const double farthest = d.index_select(0, crop).max().item<double>();
        EXPECT_GE(d.masked_select(~inside).min().item<double>(), farthest) << "crop " << c;
    }
    EXPECT_TRUE(test::throws_input_error([&] { mpu_test_crops(points, 64); }, {"more than 64"}));
}

TEST(Mpu, ChamferDropsDistancesBeyondTheThreshold) {
    at::Tensor target = test::sheet(2, 32, 7);
    at::Tensor pred = test::sheet(2, 32, 8);
    // A large threshold keeps everything: the sum of the two means (twice chamfer_loss).
    EXPECT_NEAR(mpu_chamfer(pred, target, 1e9).item<double>(),
                2 * chamfer_loss(pred, target).item<double>(), 1e-6);
    // One far outlier: with τ = 2 its distance (far above twice the mean) counts zero.
    at::Tensor outlier = target.clone();
    outlier[0][0] = at::tensor({5.0, 5.0, 5.0});
    const double loose = mpu_chamfer(outlier, target, 100).item<double>();
    const double tight = mpu_chamfer(outlier, target, 2).item<double>();
    EXPECT_LT(tight, loose);
    EXPECT_LT(tight, mpu_chamfer(target, target + 0.01, 1e9).item<double>() + 1.0);
}

TEST(Mpu, LossAtTwoTimesIsTheWeightedChamferOfTheOutput) {
    Mpu model = make(small_config());
    at::Tensor x = test::sheet(2, 16, 9), y = test::sheet(2, 32, 10);
    const double cd = mpu_chamfer(make(model.config_for_ratio(2)).upsample(x), y, 100)
                          .item<double>();  // one level: training and test paths agree
    EXPECT_NEAR(model.loss(x, y, model.parameters()).item<double>(), 50.0 * 4 * cd, 1e-4 * cd);
    // Ratio 16 runs all levels (weight 50), crops seeded by the step.
    at::Tensor y16 = test::sheet(2, 256, 11);
    at::Tensor a = model.loss(x, y16, model.parameters(), 3);
    EXPECT_TRUE(a.equal(model.loss(x, y16, model.parameters(), 3)));
    EXPECT_TRUE(std::isfinite(a.item<double>()));
    EXPECT_TRUE(test::throws_input_error(
        [&] { model.loss(x, test::sheet(2, 48, 12), model.parameters()); }, {"2^l"}));
    EXPECT_TRUE(test::throws_input_error(
        [&] { model.loss(x, test::sheet(2, 512, 12), model.parameters()); }, {"2^l"}));
}

TEST(Mpu, CurriculumAddsALevelAloneThenCombinesWithRatiosProportionalToTheirIndex) {
    std::mt19937_64 rng(1);
    const int64_t s = 10;
    auto at = [&](int64_t step) { return mpu_curriculum(step, s, 4, 2.0, rng); };
    for (int64_t step : {0, 5, 9}) {
        EXPECT_EQ(at(step).levels, 1) << step;
        EXPECT_EQ(at(step).frozen, 0);
        EXPECT_EQ(at(step).threshold, 100);
    }
    // Level l alone from S(2l − 3) for S steps, τ = 2 once past 0.6 S.
    for (int64_t l = 2; l <= 4; ++l) {
        const int64_t start = s * (2 * l - 3);
        for (int64_t step : {start, start + 6, start + 7, start + 9}) {
            MpuCurriculumStep c = at(step);
            EXPECT_EQ(c.levels, l) << step;
            EXPECT_EQ(c.frozen, l - 1) << step;
            EXPECT_EQ(c.threshold, step - start > 6 ? 2.0 : 100.0) << step;
        }
    }
    // Combined phases: P(l levels) ∝ l among the levels added so far; τ 100 only at 1 level.
    for (auto [step, newest] : {std::pair<int64_t, int64_t>{20, 2}, {45, 3}, {60, 4}, {500, 4}}) {
        std::vector<int64_t> counts(5, 0);
        const int64_t draws = 4000;
        for (int64_t i = 0; i < draws; ++i) {
            MpuCurriculumStep c = at(step);
            EXPECT_EQ(c.frozen, 0);
            EXPECT_EQ(c.threshold, c.levels == 1 ? 100.0 : 2.0);
            ++counts.at(c.levels);
        }
        const double total = double(newest * (newest + 1) / 2);
        for (int64_t l = 1; l <= 4; ++l) {
            const double expected = l <= newest ? double(l) / total : 0.0;
            EXPECT_NEAR(double(counts[l]) / draws, expected, 0.03) << step << ": " << l;
        }
    }
}

TEST(Mpu, CombinedPhasesAreTheCurriculumsStepsWithoutAFrozenLevel) {
    std::mt19937_64 rng(1);
    const int64_t s = 10;
    for (int64_t step = 0; step < 120; ++step) {
        const MpuCurriculumStep c = mpu_curriculum(step, s, 4, 2.0, rng);
        // Combined: past the first stage and no level training alone.
        EXPECT_EQ(mpu_combined_phase(step, s, 4), step >= s && c.frozen == 0) << step;
    }
    EXPECT_FALSE(mpu_combined_phase(15, s, 4));  // level 2 alone
    EXPECT_TRUE(mpu_combined_phase(25, s, 4));   // levels 1-2 combined
    EXPECT_TRUE(mpu_combined_phase(1000, s, 4));
    EXPECT_THROW(mpu_combined_phase(5, 0, 4), InputError);
}

TEST(Mpu, TrainingHalvesTheLearningRateWhenCombinedAndClipsGradients) {
    nlohmann::json config = small_config();
    config["stage_steps"] = 10;
    const Mpu model = make(config);
    for (auto [step, factor] : {std::pair<int64_t, double>{5, 1.0},
                                {15, 1.0},
                                {25, 0.5},
                                {35, 1.0},
                                {45, 0.5},
                                {95, 0.5}})
        EXPECT_DOUBLE_EQ(model.learning_rate_factor(step), factor) << step;
    for (const auto& [name, p] : model.parameters()) {
        const OptimizerGroup group = model.optimizer_group(name);
        EXPECT_DOUBLE_EQ(group.gradient_clip, 1.0) << name;
        EXPECT_DOUBLE_EQ(group.lr_scale, 1.0) << name;
        EXPECT_DOUBLE_EQ(group.weight_decay, 0.0) << name;
    }
    config["combined_lr_factor"] = 1.0;
    config["gradient_clip"] = 0.0;
    const Mpu plain = make(config);
    EXPECT_DOUBLE_EQ(plain.learning_rate_factor(25), 1.0);
    EXPECT_DOUBLE_EQ(plain.optimizer_group(plain.parameters().begin()->first).gradient_clip, 0.0);
}

TEST(Mpu, TrainingTermsFreezeEarlierLevelsWhileANewLevelTrainsAlone) {
    nlohmann::json config = small_config(4);
    config["levels"] = 2;
    config["stage_steps"] = 10;
    Mpu model = make(config);
    at::Tensor y = test::sheet(2, 64, 13);
    at::Tensor x = model.downsample(y, 14);
    auto grad_norms = [&](int64_t step) {
        LossTerms terms = model.training_terms(x, y, model.parameters(), {}, step);
        EXPECT_EQ(terms.size(), 1u);
        ParamMap grads = gradients(sum_of(terms), model.parameters());
        std::pair<double, double> norms{0, 0};
        for (const auto& [name, g] : grads)
            (name.rfind("level1.", 0) == 0 ? norms.first : norms.second) +=
                g.pow(2).sum().item<double>();
        return norms;
    };
    auto [first0, second0] = grad_norms(0);  // level 1 on the 2× subset of the target
    EXPECT_GT(first0, 0);
    EXPECT_EQ(second0, 0);
    auto [first1, second1] = grad_norms(12);  // level 2 alone
    EXPECT_EQ(first1, 0);
    EXPECT_GT(second1, 0);
    EXPECT_TRUE(test::throws_input_error(
        [&] { model.training_terms(x, y.slice(1, 0, 32), model.parameters(), {}, 0); },
        {"mpu target"}));
}

TEST(Mpu, OneFileServesEveryRatio) {
    test::TempDir dir;
    Mpu model = make(small_config());
    save_checkpoint(dir.file("mpu.pt"), model, {});
    at::Tensor cloud = test::sphere_points(40, 15);
    for (int64_t r : {2, 4, 8, 16}) {
        ServedModel served = serve(dir.file("mpu.pt"), r);
        EXPECT_EQ(served.ratio, r);
        EXPECT_EQ(served.model.backbone->ratio(), r);
        UpsampleOptions options;
        options.ratio = r;
        EXPECT_EQ(upsample_cloud(*served.model.backbone, cloud, options).points.size(0), 40 * r);
    }
    EXPECT_EQ(serve(dir.file("mpu.pt"), 0).ratio, 16);
}

}  // namespace pumeta
