// PU-Dense: parameter counts at the paper width, configs, exact output counts, the BCE loss
// against a brute-force labelling, batch-norm statistics, overfitting one cloud, and the
// second-order MAML meta-gradient through the sparse engine against finite differences.
#include "pumeta/models/pudense.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/meta/maml.h"
#include "pumeta/nn/adam.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/gradients.h"
#include "pumeta/nn/sparse/voxelize.h"
#include "pumeta/train/trainer.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

nlohmann::json tiny_config(int64_t ratio = 4, double resolution = 4) {
    return {{"backbone", "pudense"},    {"ratio", ratio},          {"channels", {4, 4, 8, 8, 8}},
            {"resolution", resolution}, {"downsampler", "random"}, {"seed", 3}};
}

std::unique_ptr<PuDense> tiny_model(int64_t ratio = 4, bool double_precision = false,
                                    double resolution = 4) {
    auto model =
        std::make_unique<PuDense>(PuDenseOptions::from_json(tiny_config(ratio, resolution)));
    if (double_precision) {
        for (auto& [name, p] : model->parameters())
            p = p.detach().to(at::kDouble).requires_grad_(true);
        for (auto& [name, b] : model->buffers()) b = b.to(at::kDouble);
    }
    return model;
}

TEST(PuDense, ParameterCountsAtThePaperWidthAndPresets) {
    EXPECT_EQ(
        count_parameters(PuDense(PuDenseOptions::from_json(nlohmann::json::object())).parameters()),
        13172441);
    EXPECT_EQ(count_parameters(
                  PuDense(PuDenseOptions::from_json({{"last_kernel_size", 7}})).parameters()),
              13842137);
    EXPECT_EQ(
        count_parameters(PuDense(PuDenseOptions::from_json({{"preset", "compact"}})).parameters()),
        1603757);
}

TEST(PuDense, ConfigRoundTripsAndRejectsInvalidFields) {
    PuDenseOptions options = PuDenseOptions::from_json(
        {{"preset", "compact"}, {"ratio", 4}, {"resolution", 16}, {"seed", 7}});
    EXPECT_EQ(options.channels, (std::vector<int64_t>{16, 16, 32, 64, 64}));
    nlohmann::json j = options.to_json();
    EXPECT_EQ(PuDenseOptions::from_json(j).to_json(), j);
    // Explicit channels win over the preset, whatever the key order.
    EXPECT_EQ(
        PuDenseOptions::from_json({{"channels", {8, 8, 8, 8, 8}}, {"preset", "compact"}}).channels,
        (std::vector<int64_t>{8, 8, 8, 8, 8}));
    auto model = make_backbone(j);
    EXPECT_EQ(model->name(), "pudense");
    EXPECT_EQ(model->ratio(), 4);
    for (nlohmann::json bad :
         {nlohmann::json{{"colour", 1}}, nlohmann::json{{"preset", "huge"}},
          nlohmann::json{{"channels", {8, 8, 8}}},
          nlohmann::json{{"channels", {8, 16, 16, 16, 16}}},
          nlohmann::json{{"channels", {6, 6, 8, 8, 8}}}, nlohmann::json{{"last_kernel_size", 4}},
          nlohmann::json{{"resolution", 0}}, nlohmann::json{{"downsampler", "magic"}}})
        EXPECT_THROW(PuDenseOptions::from_json(bad), InputError) << bad.dump();
}

TEST(PuDense, ShippedConfigBuildsTheCompactX8Model) {
    std::ifstream file(test::source_dir() + "/configs/pudense-x8.json");
    ASSERT_TRUE(file) << "configs/pudense-x8.json";
    TrainConfig config = TrainConfig::from_json(nlohmann::json::parse(file));
    auto model = make_backbone(config.backbone);
    EXPECT_EQ(model->name(), "pudense");
    EXPECT_EQ(model->ratio(), 8);
    EXPECT_EQ(count_parameters(model->parameters()), 1603757);
}

TEST(PuDense, UpsampleGivesExactlyRNVoxelCentresNearTheInput) {
    at::Tensor x = test::sheet(2, 40, 1);
    // r = 400 asks for more voxels than the generative layer proposes: they repeat.
    for (int64_t ratio : {2, 4, 8, 400}) {
        auto model = tiny_model(ratio);
        at::Tensor y = model->upsample(x);
        ASSERT_EQ(y.sizes(), (std::vector<int64_t>{2, 40 * ratio, 3})) << "r = " << ratio;
        const double h = model->voxel_size();
        // Centres of voxels: (i + 0.5)·h.
        at::Tensor cells = y / h - 0.5;
        EXPECT_LT((cells - cells.round()).abs().max().item<double>(), 1e-4);
        // A generated voxel is within 2 voxels of a stride-2 site, itself within 1 voxel of an
        // input voxel: at most 3.5 h from some input point (L∞).
        for (int64_t b = 0; b < 2; ++b) {
            at::Tensor gap = (y[b].unsqueeze(1) - x[b].unsqueeze(0)).abs().amax(2).amin(1);
            EXPECT_LE(gap.max().item<double>(), 3.5 * h + 1e-5) << "r = " << ratio;
        }
        if (ratio <= 8)  // enough candidates: all distinct
            EXPECT_EQ(std::get<0>(at::unique_dim(y[0], 0)).size(0), 40 * ratio);
    }
}

TEST(PuDense, EachPatchUpsamplesTheSameAloneAsInABatch) {
    // Why upsample_cloud may use the backbone's small inference batch without changing results.
    at::Tensor x = test::sheet(3, 40, 5);
    auto model = tiny_model(4);
    at::Tensor together = model->upsample(x);
    // The same voxels: a patch's sites go through the products with others' (a different row
    // count), so logits may differ in the last bit (1-2 ulp measured) and swap two voxels at
    // the top-k cut; at most 1 % of the voxels may differ by such swaps.
    for (int64_t b = 0; b < 3; ++b) {
        at::Tensor alone = model->upsample(x.slice(0, b, b + 1))[0];
        ASSERT_EQ(alone.sizes(), together[b].sizes());
        const int64_t n = alone.size(0);
        const int64_t distinct =
            std::get<0>(at::unique_dim(at::cat({alone, together[b]}), 0)).size(0);
        EXPECT_LE(distinct - n, n / 100) << "patch " << b << ": " << distinct - n << " of " << n;
    }
    EXPECT_EQ(model->inference_batch_patches(), 2);
}

TEST(PuDense, DiagnoseDecomposesTheErrorIntoVoxelFloorCandidatesAndRanking) {
    auto model = tiny_model(4);
    at::Tensor y = test::sheet(2, 160, 5);
    at::Tensor x = y.slice(1, 0, 160, 4).contiguous();
    nlohmann::json d = model->diagnose(x, y);
    ASSERT_EQ(d["floor_cd"].size(), 2u);
    const double h = model->voxel_size();
    at::Tensor output = model->upsample(x);
    for (int b = 0; b < 2; ++b) {
        const double floor = d["floor_cd"][b], candidates = d["candidates_cd"][b];
        const double recall = d["candidate_recall"][b], precision = d["precision"][b];
        // Snapping moves each point by at most half a voxel diagonal.
        EXPECT_GT(floor, 0.0);
        EXPECT_LE(floor, 2 * 0.75 * h * h);
        EXPECT_GE(recall, 0.0);
        EXPECT_LE(recall, 1.0);
        EXPECT_GE(precision, 0.0);
        EXPECT_LE(precision, 1.0);
        // The best choice among the candidates is no worse than the network's own.
        const double model_cd =
            2.0 * chamfer_loss(output.slice(0, b, b + 1), y.slice(0, b, b + 1)).item<double>();
        EXPECT_LE(candidates, model_cd + 1e-9);
    }
    // A target made of voxel centres is its own ideal output: the floor is 0.
    at::Tensor centres = (at::floor(y / h) + 0.5) * h;
    nlohmann::json exact = model->diagnose(x, centres.to(at::kFloat));
    EXPECT_NEAR(exact["floor_cd"][0].get<double>(), 0.0, 1e-10);
}

TEST(PuDense, LossIsBceAgainstMembershipInTheTargetVoxels) {
    auto model = tiny_model();
    at::Tensor target = test::sheet(2, 64, 2);
    at::Tensor input = target.narrow(1, 0, 16);
    at::Tensor loss = model->loss(input, target, model->parameters());

    Occupancy occ = model->occupancy(model->voxels(input), model->parameters(), {});
    const double h = model->voxel_size();
    std::set<std::array<int64_t, 4>> truth;
    for (int64_t b = 0; b < 2; ++b)
        for (int64_t i = 0; i < 64; ++i)
            truth.insert({b, int64_t(std::floor(target[b][i][0].item<double>() / h)),
                          int64_t(std::floor(target[b][i][1].item<double>() / h)),
                          int64_t(std::floor(target[b][i][2].item<double>() / h))});
    at::Tensor sites = occ.sites->coords().to(at::kLong);
    double total = 0;
    int64_t positives = 0;
    for (int64_t g = 0; g < sites.size(0); ++g) {
        bool member = truth.count({sites[g][0].item<int64_t>(), sites[g][1].item<int64_t>(),
                                   sites[g][2].item<int64_t>(), sites[g][3].item<int64_t>()});
        positives += member;
        double z = occ.logits[g].item<double>();
        total += std::log1p(std::exp(-std::abs(z))) + std::max(z, 0.0) - (member ? z : 0.0);
    }
    EXPECT_GT(positives, 0);
    EXPECT_NEAR(loss.item<double>(), total / double(sites.size(0)), 1e-5);
}

TEST(PuDense, LossUsesBatchStatisticsAndOnlyUpdateBuffersMovesRunningOnes) {
    auto model = tiny_model();
    at::Tensor target = test::sheet(1, 64, 3);
    at::Tensor input = target.narrow(1, 0, 16);
    double before = model->loss(input, target, model->parameters()).item<double>();
    ParamMap saved;
    for (auto& [name, b] : model->buffers()) saved[name] = b.clone();
    at::Tensor y_before = model->upsample(input);
    for (auto& [name, b] : model->buffers()) EXPECT_TRUE(b.equal(saved[name])) << name;

    model->update_buffers(input, model->parameters());
    int64_t moved = 0;
    for (auto& [name, b] : model->buffers()) moved += !b.equal(saved[name]);
    EXPECT_EQ(moved, int64_t(saved.size()));
    // The loss ignores running statistics; inference uses them.
    EXPECT_DOUBLE_EQ(model->loss(input, target, model->parameters()).item<double>(), before);
    EXPECT_FALSE(model->upsample(input).equal(y_before));
}

TEST(PuDense, RepeatedCallsOnTheSameInputReuseItsKernelMaps) {
    auto model = tiny_model();
    at::Tensor target = test::sheet(1, 64, 4);
    at::Tensor input = target.narrow(1, 0, 16).clone();
    CoordinateSetPtr voxels = model->voxels(input);
    model->loss(input, target, model->parameters());
    const int64_t built = voxels->kernel_maps_built();
    EXPECT_GT(built, 0);
    model->loss(input.clone(), target, model->parameters());  // equal content, new tensor
    model->update_buffers(input, model->parameters());
    EXPECT_EQ(model->voxels(input.clone()), voxels);
    EXPECT_EQ(voxels->kernel_maps_built(), built);
}

/// Fraction of the target's voxels among the voxels of the upsampled points (rN of them, at
/// least as many as the target's voxels, so a perfect model scores 1).
double voxel_recall(const PuDense& model, const at::Tensor& input, const at::Tensor& target) {
    CoordinateSetPtr truth = voxelize(target, model.voxel_size());
    CoordinateSetPtr kept = voxelize(model.upsample(input), model.voxel_size());
    return (truth->lookup(kept->coords()) >= 0).sum().item<double>() / double(truth->size());
}

TEST(PuDense, OverfitsOneSmallCloud) {
    nlohmann::json config = tiny_config(4);
    config["batch_stats_at_inference"] = true;  // no running statistics are trained here
    PuDense model(PuDenseOptions::from_json(config));
    at::Tensor target = test::sheet(1, 96, 5);
    at::Tensor input = target.narrow(1, 0, 24);
    ParamMap& params = model.parameters();
    const double recall_before = voxel_recall(model, input, target);
    AdamOptions adam_options;
    adam_options.lr = 2e-2;
    Adam adam(params, adam_options);
    double first = 0, last = 0;
    for (int step = 0; step < 30; ++step) {
        at::Tensor loss = model.loss(input, target, params);
        (step == 0 ? first : last) = loss.item<double>();
        adam.step(gradients(loss, params));
    }
    EXPECT_LT(last, 0.5 * first) << "first " << first << ", last " << last;
    // Not just the base rate: the kept voxels become the target's.
    const double recall_after = voxel_recall(model, input, target);
    EXPECT_GT(recall_after, 0.9) << "before " << recall_before;
    EXPECT_GT(recall_after, recall_before + 0.2);
}

nlohmann::json refined_config(double range = 1.0) {
    nlohmann::json config = tiny_config(4);
    config["refine"] = true;
    config["refine_range"] = range;
    config["batch_stats_at_inference"] = true;
    return config;
}

TEST(PuDense, RefinementStartsAtTheFaithfulOutputsAndOffTheGrid) {
    PuDense faithful(PuDenseOptions::from_json(tiny_config(4)));
    PuDense refined(PuDenseOptions::from_json(refined_config()));
    EXPECT_DOUBLE_EQ(faithful.output_grid(), faithful.voxel_size());
    EXPECT_EQ(refined.output_grid(), 0.0);
    // The same seed draws the faithful network's weights first; the refinement adds its own.
    int64_t shared = 0;
    for (const auto& [name, p] : faithful.parameters()) {
        ASSERT_TRUE(refined.parameters().count(name)) << name;
        EXPECT_TRUE(refined.parameters().at(name).equal(p)) << name;
        ++shared;
    }
    EXPECT_EQ(int64_t(refined.parameters().size()), shared + 4);
    at::Tensor target = test::sheet(2, 64, 7);
    at::Tensor input = target.narrow(1, 0, 16);
    // Running statistics as the faithful model's: only the zero-initialised offsets differ.
    for (auto& [name, b] : refined.buffers()) b.copy_(faithful.buffers().at(name));
    nlohmann::json batch_config = tiny_config(4);
    batch_config["batch_stats_at_inference"] = true;
    PuDense faithful_batch(PuDenseOptions::from_json(batch_config));
    EXPECT_TRUE(refined.upsample(input).equal(faithful_batch.upsample(input)));
    const LossTerms terms = refined.loss_terms(input, target, refined.parameters());
    ASSERT_EQ(terms.size(), 2u);
    EXPECT_EQ(terms[0].first, "bce");
    EXPECT_EQ(terms[1].first, "refine_cd");
    EXPECT_DOUBLE_EQ(terms[0].second.item<double>(),
                     faithful.loss(input, target, faithful.parameters()).item<double>());
}

TEST(PuDense, RefinementOffsetsStayWithinTheirRangeOfTheVoxelCentres) {
    PuDense refined(PuDenseOptions::from_json(refined_config(/*range=*/0.5)));
    {
        at::NoGradGuard no_grad;
        refined.parameters().at("refine.offset.bias").fill_(50.0);  // tanh saturates
    }
    at::Tensor input = test::sheet(1, 64, 8).narrow(1, 0, 16);
    at::Tensor moved = refined.upsample(input)[0];
    const double h = refined.voxel_size();
    // Voxel centres lie at (i + 0.5)·h; offsets saturated at +0.5 h move every coordinate to a
    // multiple of h.
    at::Tensor steps = moved / h;
    EXPECT_LT((steps - steps.round()).abs().max().item<double>(), 1e-4);
    at::Tensor centres = PuDense(PuDenseOptions::from_json(tiny_config(4))).upsample(input)[0] / h;
    EXPECT_GT((centres - centres.round()).abs().min().item<double>(), 0.49);
}

TEST(PuDense, RefinementLearnsOffsetsThatLowerTheChamferDistance) {
    PuDense refined(PuDenseOptions::from_json(refined_config()));
    at::Tensor target = test::sheet(1, 96, 9);
    at::Tensor input = target.narrow(1, 0, 24);
    ParamMap& params = refined.parameters();
    auto cd = [&] { return chamfer_loss(refined.upsample(input), target).item<double>(); };
    // Learn the occupancy first, then compare the refinement's CD term before and after.
    AdamOptions adam_options;
    adam_options.lr = 2e-2;
    Adam adam(params, adam_options);
    for (int step = 0; step < 60; ++step)
        adam.step(gradients(refined.loss(input, target, params), params));
    PuDense faithful(PuDenseOptions::from_json(refined_config()));
    for (auto& [name, p] : faithful.parameters()) {
        at::NoGradGuard no_grad;
        p.copy_(params.at(name));
    }
    {
        at::NoGradGuard no_grad;
        faithful.parameters().at("refine.offset.weight").zero_();
        faithful.parameters().at("refine.offset.bias").zero_();
    }
    const double centres = chamfer_loss(faithful.upsample(input), target).item<double>();
    EXPECT_LT(cd(), 0.95 * centres) << "voxel centres " << centres;
}

TEST(PuDense, DownsamplerKeepsAUniformRandomSubset) {
    auto model = tiny_model(4);
    at::Tensor dense = test::sheet(2, 64, 6);
    at::Tensor sparse = model->downsample(dense, 9);
    ASSERT_EQ(sparse.sizes(), (std::vector<int64_t>{2, 16, 3}));
    for (int64_t b = 0; b < 2; ++b) {
        at::Tensor d = (sparse[b].unsqueeze(1) - dense[b].unsqueeze(0)).abs().sum(2);
        EXPECT_EQ(d.amin(1).max().item<double>(), 0.0);  // every point is an input point
    }
    EXPECT_TRUE(model->downsample(dense, 9).equal(sparse));
}

}  // namespace
}  // namespace pumeta
