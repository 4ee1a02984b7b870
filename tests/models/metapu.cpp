// Meta-PU: the paper's parameter count, any ratio from one set of weights, the generated
// weights (constant per scale, differentiable), the scale code and the training draw.
#include "pumeta/models/metapu.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <cmath>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/gradients.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

MetaPu small() { return MetaPu(MetaPuOptions::from_json(metapu_small_config())); }

TEST(MetaPu, PaperWidthHasTheOriginalsParameterCount) {
    MetaPu paper(MetaPuOptions{});
    // models/README.md, "Meta-PU": 33,152 + 1,477,760 + 1,510,528.
    EXPECT_EQ(count_parameters(paper.parameters()), 3021440);
    int64_t generators = 0;
    for (const auto& [name, p] : paper.parameters()) {
        EXPECT_EQ(name.find("meta"), std::string::npos) << name;
        if (name.find(".scale_weights.") != std::string::npos) generators += p.numel();
    }
    EXPECT_EQ(generators, 4 * 573504);
}

TEST(MetaPu, OptimizerGroupsAreTheOriginals) {
    MetaPu paper(MetaPuOptions{});
    int64_t fast = 0, slow = 0;
    for (const auto& [name, p] : paper.parameters()) {
        const OptimizerGroup group = paper.optimizer_group(name);
        EXPECT_DOUBLE_EQ(group.weight_decay, 1e-5) << name;
        const bool generator = name.find(".scale_weights.") != std::string::npos;
        EXPECT_EQ(metapu_generator_parameter(name), generator) << name;
        EXPECT_DOUBLE_EQ(group.lr_scale, generator ? 10.0 : 1.0) << name;
        (generator ? fast : slow) += p.numel();
    }
    // 1e-3 for the four generators' 4 × 573,504 values, 1e-4 for the other 727,424.
    EXPECT_EQ(fast, 4 * 573504);
    EXPECT_EQ(slow, 3021440 - 4 * 573504);

    nlohmann::json config = metapu_small_config();
    config["generator_lr_scale"] = 3.0;
    config["weight_decay"] = 0.0;
    MetaPu custom(MetaPuOptions::from_json(config));
    for (const auto& [name, p] : custom.parameters()) {
        EXPECT_DOUBLE_EQ(custom.optimizer_group(name).weight_decay, 0.0);
        EXPECT_DOUBLE_EQ(custom.optimizer_group(name).lr_scale,
                         metapu_generator_parameter(name) ? 3.0 : 1.0);
    }
}

TEST(MetaPu, EveryRatioTwoToSixteenGivesFloorNTimesRPoints) {
    MetaPu model = small();
    at::NoGradGuard no_grad;
    for (int64_t n : {16, 23}) {
        at::Tensor x = test::sheet(1, n, 1);
        for (int64_t r = 2; r <= 16; ++r) {
            MetaPu at_ratio(MetaPuOptions::from_json(model.config_for_ratio(r)));
            at::Tensor y = at_ratio.upsample(x, model.parameters());
            EXPECT_EQ(y.sizes(), (std::vector<int64_t>{1, n * r, 3})) << n << " x" << r;
            EXPECT_TRUE(y.isfinite().all().item<bool>());
        }
        // Non-integer scales through forward(): ⌊N·R⌋ points.
        for (double scale : {1.1, 2.5, 7.3, 15.9}) {
            const int64_t want = int64_t(std::floor(n * scale));
            at::Tensor y = model.forward(x, model.parameters(), scale, want).points;
            EXPECT_EQ(y.size(1), want) << scale;
        }
    }
}

TEST(MetaPu, RatiosOutsideTwoToSixteenAreOneLineInputErrors) {
    MetaPu model = small();
    // The weights serve no other ratio: no config (serve() then refuses the ratio).
    for (int64_t r : {0, 1, 17, 64}) EXPECT_TRUE(model.config_for_ratio(r).is_null()) << r;
    nlohmann::json config = metapu_small_config();
    config["ratio"] = 17;
    EXPECT_TRUE(test::throws_input_error([&] { make_metapu(config); }, {"'ratio' 17"}));
    at::Tensor x = test::sheet(1, 8, 2);
    EXPECT_TRUE(test::throws_input_error(
        [&] { model.loss(x, test::sheet(1, 8 * 17, 3), model.parameters()); }, {"scale 17"}));
}

TEST(MetaPu, ConfigForRatioKeepsTheOutputPointsPerPatch) {
    MetaPu model(MetaPuOptions{});  // 256 points at 16x
    EXPECT_EQ(model.config_for_ratio(4)["patch_size"], 1024);
    EXPECT_EQ(model.config_for_ratio(3)["patch_size"], 1365);
    EXPECT_EQ(model.config_for_ratio(16)["ratio"], 16);
}

// The generated matrices enter only through the scale code: the penalty Σ ½‖W‖² is a
// function of the code alone.
double penalty(const MetaPu& model, const at::Tensor& x, double scale) {
    const int64_t n = x.size(1);
    return model.forward(x, model.parameters(), scale, int64_t(std::floor(n * scale)))
        .scale_weights_norm.item<double>();
}

TEST(MetaPu, GeneratedWeightsAreConstantPerScaleAndDifferentiable) {
    MetaPu model = small();
    at::Tensor a = test::sheet(2, 16, 4), b = test::sheet(1, 20, 5);
    // Same scale, other inputs: the same matrices.
    EXPECT_DOUBLE_EQ(penalty(model, a, 4.0), penalty(model, b, 4.0));
    // Another scale: other matrices.
    EXPECT_NE(penalty(model, a, 4.0), penalty(model, a, 9.0));
    // Differentiable w.r.t. every generator tensor, twice (MAML's inner loop).
    MetaPuOutput out = model.forward(a, model.parameters(), 4.0, 64);
    ParamMap generators;
    for (const auto& [name, p] : model.parameters())
        if (name.find(".scale_weights.") != std::string::npos) generators[name] = p;
    ASSERT_EQ(generators.size(), 4u * 6u);
    std::vector<at::Tensor> inputs;
    for (const auto& [name, p] : generators) inputs.push_back(p);
    at::Tensor objective = out.points.pow(2).sum() + out.scale_weights_norm;
    std::vector<at::Tensor> grads = torch::autograd::grad({objective}, inputs, {}, true, true);
    at::Tensor sum = at::zeros({}, objective.options());
    for (size_t i = 0; i < grads.size(); ++i) {
        ASSERT_TRUE(grads[i].defined());
        EXPECT_GT(grads[i].abs().max().item<double>(), 0)
            << std::next(generators.begin(), i)->first;
        sum = sum + grads[i].pow(2).sum();
    }
    std::vector<at::Tensor> second = torch::autograd::grad({sum}, inputs, {}, true, true);
    EXPECT_TRUE(second.back().defined());
}

TEST(MetaPu, ScaleCodeUsesTheNearestGridEntry) {
    // √R_q / 4 with R_q rounded to the 0.1 grid: 4 maps to 4.0 (the original's truncation
    // gives 3.9), 3 to 3.0; the ends clamp.
    EXPECT_DOUBLE_EQ(metapu_scale_code(2.0, 4), std::sqrt(4.0) / 4);
    EXPECT_DOUBLE_EQ(metapu_scale_code(std::sqrt(3.0), 4), std::sqrt(3.0) / 4);
    EXPECT_DOUBLE_EQ(metapu_scale_code(std::sqrt(2.0004), 4), std::sqrt(2.0) / 4);
    EXPECT_DOUBLE_EQ(metapu_scale_code(1.0, 4), std::sqrt(1.1) / 4);
    EXPECT_DOUBLE_EQ(metapu_scale_code(5.0, 4), 1.0);
}

TEST(MetaPu, TrainingScalesCoverTheGridDeterministically) {
    std::set<int64_t> seen;
    for (int64_t step = 0; step < 3000; ++step) {
        const double r = metapu_training_scale(step, 16);
        EXPECT_EQ(r, metapu_training_scale(step, 16));
        EXPECT_GE(r, 1.1 - 1e-12);
        EXPECT_LE(r, 16.0 + 1e-12);
        seen.insert(std::llround(r * 10));
    }
    EXPECT_EQ(seen.size(), 150u);
}

TEST(MetaPu, TrainingTermsDrawTheInputFromTheGroundTruthAtTheStepsScale) {
    MetaPu model = small();
    at::Tensor gt = test::sheet(2, 64, 6);
    at::Tensor ignored = test::sheet(2, 16, 7);
    LossTerms a = model.training_terms(ignored, gt, model.parameters(), {}, 5);
    LossTerms b = model.training_terms(test::sheet(2, 16, 8), gt, model.parameters(), {}, 5);
    ASSERT_EQ(a.size(), 4u);
    EXPECT_EQ(a[0].first, "sinkhorn");
    // The given input is not used; the step decides.
    for (size_t i = 0; i < a.size(); ++i)
        EXPECT_EQ(a[i].second.item<double>(), b[i].second.item<double>()) << a[i].first;
    EXPECT_TRUE(std::isfinite(sum_of(a).item<double>()));
}

TEST(MetaPu, ChamferReconstructionReplacesTheSinkhornTermOnly) {
    nlohmann::json config = metapu_small_config();
    MetaPu sinkhorn(MetaPuOptions::from_json(config));
    config["reconstruction"] = "chamfer";
    MetaPu chamfer(MetaPuOptions::from_json(config));
    EXPECT_EQ(MetaPuOptions::from_json(chamfer.config()).reconstruction, "chamfer");
    at::Tensor gt = test::sheet(2, 64, 9);
    at::Tensor input = gt.narrow(1, 0, 16);
    LossTerms a = sinkhorn.loss_terms(input, gt, sinkhorn.parameters());
    LossTerms b = chamfer.loss_terms(input, gt, chamfer.parameters());
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(b[0].first, "chamfer");
    at::Tensor out = chamfer.forward(input, chamfer.parameters(), 4.0, 64).points;
    EXPECT_NEAR(b[0].second.item<double>(), chamfer_loss(out, gt).item<double>(), 1e-6);
    for (size_t i = 1; i < a.size(); ++i) {
        EXPECT_EQ(a[i].first, b[i].first);
        EXPECT_EQ(a[i].second.item<double>(), b[i].second.item<double>()) << a[i].first;
    }
    config["reconstruction"] = "emd";
    EXPECT_THROW(MetaPuOptions::from_json(config), InputError);
}

TEST(MetaPu, SparseInputKeepsDistinctPointsOfTheCloud) {
    at::Tensor dense = test::sheet(2, 100, 9);
    for (int64_t m : {10, 50, 51, 90}) {
        at::Tensor sparse = metapu_sparse_input(dense, m, 3);
        ASSERT_EQ(sparse.sizes(), (std::vector<int64_t>{2, m, 3}));
        for (int64_t b = 0; b < 2; ++b) {
            // Every kept point is a point of the cloud, none twice.
            at::Tensor d = (sparse[b].unsqueeze(1) - dense[b].unsqueeze(0)).pow(2).sum(-1);
            at::Tensor nearest = std::get<1>(d.min(1));
            EXPECT_EQ(std::get<0>(d.min(1)).max().item<float>(), 0.0f);
            EXPECT_EQ(std::get<0>(at::_unique(nearest)).numel(), m);
        }
        EXPECT_TRUE(sparse.equal(metapu_sparse_input(dense, m, 3)));
    }
}

}  // namespace
}  // namespace pumeta
