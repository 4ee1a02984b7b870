// Dis-PU: parameter counts against the original's layer list, shapes, structural properties
// (copy order, bounded offsets, permutation equivariance), the loss and its schedule, batch
// norm buffers, checkpoints, meta-gradients and the whole-cloud pipeline.
#include "pumeta/models/dispu.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/inference/upsample.h"
#include "pumeta/meta/maml.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/nn/adam.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/gradients.h"
#include "pumeta/nn/repulsion_loss.h"
#include "pumeta/train/trainer.h"
#include "pumeta/train/training_state.h"
#include "support/test_util.h"

namespace pumeta {

namespace {

// A very small Dis-PU for tests that train, differentiate twice or run many passes.
using test::tiny_dispu_config;

DisPu make(const nlohmann::json& config) { return DisPu(DisPuOptions::from_json(config)); }

// Dis-PU's trainable variables counted from the original's layer list (generator.py,
// ops.py: feature_extraction_GCN, duplicate_up, coordinate_regressor, PointShuffle2), every
// convolution with weights and biases. Written independently of the model's construction.
struct Widths {
    int64_t growth, blocks, k, expand, feature, regressor, bottleneck, refiner, out, attention;
};

int64_t original_parameter_count(const Widths& w) {
    auto conv = [](int64_t in, int64_t out) { return in * out + out; };
    const int64_t g = w.growth;
    int64_t total = conv(3, g);  // layer0
    int64_t channels = g;
    for (int64_t b = 0; b < w.blocks; ++b) {
        int64_t in = g;
        if (b > 0) {
            total += conv(channels, 2 * g);  // layer<b>_prep compression
            in = 2 * g;
        }
        // dense_conv: l0 on [x_i, x_j − x_i], l1 on [l0, x_i], l2 on [l1, l0, x_i].
        total += conv(2 * in, g) + conv(g + in, g) + conv(2 * g + in, g);
        channels = (b == 0 ? g : channels) + 3 * g + in;
    }
    auto regressor = [&](int64_t in) {
        return conv(in, w.regressor) + conv(w.regressor, w.bottleneck) + conv(w.bottleneck, 3);
    };
    total += conv(channels + 2, w.expand) + conv(w.expand, w.feature);  // duplicate_up
    total += regressor(w.feature);                                      // coarse
    const int64_t grouped = 3 + 3 + w.feature;                          // [rel xyz, xyz, feature]
    total += conv(grouped, w.refiner) + conv(w.refiner, w.refiner);     // local shared MLPs
    total += conv(3, w.k) + 2 * w.k;                                    // weight net + BN
    total += conv(w.refiner * w.k, w.out);                              // [1, C] after_conv
    total += conv(grouped, w.out);                                      // skip
    total += conv(w.feature, 2 * w.attention) + conv(w.feature, w.attention) +
             conv(w.attention, w.out);  // non-local: kv, query, back projection
    total += conv(w.out, w.out);        // aggregation
    total += regressor(w.out);          // fine
    return total;
}

std::vector<at::Tensor> values(const ParamMap& params) {
    std::vector<at::Tensor> out;
    for (const auto& [name, tensor] : params) out.push_back(tensor);
    return out;
}

ParamMap snapshot(const ParamMap& map) {
    ParamMap out;
    for (const auto& [name, t] : map) out[name] = t.detach().clone();
    return out;
}

bool same(const ParamMap& a, const ParamMap& b) {
    if (a.size() != b.size()) return false;
    for (const auto& [name, t] : a)
        if (!b.count(name) || !t.equal(b.at(name))) return false;
    return true;
}

}  // namespace

TEST(DisPu, ParameterCountsMatchTheOfficialModel) {
    // Paper width, by the original's layers: feature extractor 58,128 (layer0 96; block 1
    // 4,104; blocks 2-4 compressions 5,808 + 11,568 + 17,328 and dense convs 3 × 6,408);
    // duplicate-up 482->256->128: 156,544; coarse regressor 128->256->64->3: 49,667;
    // refiner 700,192 (local 17,280 + 16,512; weight net 3->16 with BN gamma/beta 96;
    // [1,128] kernel 16->256: 524,544; skip 134->256: 34,560; non-local 16,512 + 8,256 +
    // 16,640; aggregation 65,792); fine regressor 256->256->64->3: 82,435. Total 1,046,966
    // (the paper's "1.047 M"), the same for every r: the grid code is always 2-D.
    const Widths paper{24, 4, 16, 256, 128, 256, 64, 128, 256, 64};
    EXPECT_EQ(original_parameter_count(paper), 1046966);
    for (int64_t ratio : {4, 8, 16}) {
        DisPu model = make({{"ratio", ratio}});
        EXPECT_EQ(count_parameters(model.parameters()), 1046966) << "r = " << ratio;
    }
    const Widths compact{12, 4, 16, 128, 64, 128, 32, 64, 128, 32};
    DisPu model = make({{"preset", "compact"}});
    EXPECT_EQ(count_parameters(model.parameters()), original_parameter_count(compact));
    EXPECT_EQ(count_parameters(model.parameters()), 263374);
    // Buffers are not parameters: running mean and variance of 16 channels and the step count.
    EXPECT_EQ(count_parameters(model.buffers()), 33);
}

TEST(DisPu, OutputShapesForEveryRatioAtPaperWidth) {
    at::Tensor x = test::sheet(1, 256, 1);
    at::NoGradGuard no_grad;
    for (int64_t ratio : {4, 8, 16}) {
        DisPu model = make({{"ratio", ratio}});
        DisPuOutput out = model.forward(x, model.parameters(), NormStatistics::kRunning);
        std::vector<int64_t> expected{1, 256 * ratio, 3};
        EXPECT_EQ(out.coarse.sizes(), expected) << "r = " << ratio;
        EXPECT_EQ(out.fine.sizes(), expected) << "r = " << ratio;
        EXPECT_TRUE(out.fine.isfinite().all().item<bool>());
        EXPECT_LE((out.fine - out.coarse).abs().max().item<double>(), 0.5);
        EXPECT_TRUE(model.upsample(x).equal(out.fine));
    }
}

TEST(DisPu, GridCodeFollowsTheOriginalFactorisation) {
    EXPECT_TRUE(at::allclose(
        dispu_grid(4), at::tensor({-.2f, -.2f, .2f, -.2f, -.2f, .2f, .2f, .2f}).view({4, 2})));
    // 8 = 2 × 4: x in {−0.2, 0.2} fastest, y in 4 steps.
    float t = 0.2f / 3;
    EXPECT_TRUE(at::allclose(dispu_grid(8), at::tensor({-.2f, -.2f, .2f, -.2f, -.2f, -t, .2f, -t,
                                                        -.2f, t, .2f, t, -.2f, .2f, .2f, .2f})
                                                .view({8, 2})));
    // 3 = 1 × 3 (a single x value is the range's start); 1 = 1 × 1.
    EXPECT_TRUE(
        at::allclose(dispu_grid(3), at::tensor({-.2f, -.2f, -.2f, 0.f, -.2f, .2f}).view({3, 2})));
    EXPECT_TRUE(at::allclose(dispu_grid(1), at::tensor({-.2f, -.2f}).view({1, 2})));
    at::Tensor g16 = dispu_grid(16);
    EXPECT_EQ(std::get<0>(at::_unique(g16.select(1, 0))).numel(), 4);
    EXPECT_EQ(std::get<0>(at::_unique(g16.select(1, 1))).numel(), 4);
    EXPECT_THROW(dispu_grid(0), InputError);
}

TEST(DisPu, DuplicatesAreCopyMajorAndDifferOnlyByTheirGridCode) {
    DisPu model = make(tiny_dispu_config());
    at::Tensor x = test::sheet(2, 16, 2);
    ParamMap params = model.parameters();
    at::NoGradGuard no_grad;
    at::Tensor coarse = model.forward(x, params, NormStatistics::kRunning).coarse;
    at::Tensor copies = coarse.view({2, 4, 16, 3});  // row s·N + i
    EXPECT_GT((copies.select(1, 1) - copies.select(1, 0)).abs().max().item<double>(), 1e-3);
    // Without the grid's columns in duplicate-up, the r copies of a point coincide: up to
    // rounding, as the copies are different rows of the same products, which some OpenBLAS
    // kernels (Haswell, Zen) round by row position (3.7e-8 measured; about 30 ulp allowed).
    at::Tensor w = params.at("up.conv1.weight").clone();
    w.narrow(1, w.size(1) - 2, 2).zero_();
    params["up.conv1.weight"] = w;
    copies = model.forward(x, params, NormStatistics::kRunning).coarse.view({2, 4, 16, 3});
    for (int64_t s = 1; s < 4; ++s)
        EXPECT_TRUE(at::allclose(copies.select(1, s), copies.select(1, 0), /*rtol=*/0, 1e-6));
}

TEST(DisPu, CoarseResidualAddsEachInputPointToItsCopies) {
    nlohmann::json config = tiny_dispu_config();
    DisPu absolute = make(config);
    config["coarse_residual"] = true;
    DisPu residual = make(config);
    EXPECT_EQ(residual.config()["coarse_residual"], true);
    EXPECT_EQ(absolute.config()["coarse_residual"], false);
    at::Tensor x = test::sheet(2, 16, 4);
    at::NoGradGuard no_grad;
    // Same seed, same parameters: only the added input differs.
    at::Tensor plain = absolute.forward(x, absolute.parameters(), NormStatistics::kRunning).coarse;
    at::Tensor shifted =
        residual.forward(x, residual.parameters(), NormStatistics::kRunning).coarse;
    at::Tensor copies = (shifted - plain).view({2, 4, 16, 3});  // row s·N + i
    for (int64_t s = 0; s < 4; ++s)
        EXPECT_TRUE(at::allclose(copies.select(1, s), x, 1e-5, 1e-6)) << "copy " << s;
}

TEST(DisPu, OffsetsAreBoundedAndAddedToTheCoarsePoints) {
    DisPu model = make(tiny_dispu_config());
    at::Tensor x = test::sheet(2, 16, 3);
    ParamMap params = model.parameters();
    params["fine.fc2.weight"] = at::zeros_like(params["fine.fc2.weight"]);
    params["fine.fc2.bias"] = at::tensor({100.f, -100.f, 0.f});
    at::NoGradGuard no_grad;
    DisPuOutput out = model.forward(x, params, NormStatistics::kBatch);
    at::Tensor offset = (out.fine - out.coarse).view({-1, 3});
    EXPECT_TRUE(at::allclose(offset, at::tensor({0.5f, -0.5f, 0.f}).expand_as(offset), 0, 1e-6));
}

TEST(DisPu, CoarseOutputDoesNotDependOnTheRefiner) {
    DisPu model = make(tiny_dispu_config());
    at::Tensor x = test::sheet(1, 16, 4);
    ParamMap params = model.parameters();
    at::NoGradGuard no_grad;
    DisPuOutput before = model.forward(x, params, NormStatistics::kBatch);
    for (auto& [name, p] : params)
        if (name.rfind("refine.", 0) == 0 || name.rfind("fine.", 0) == 0) p = p + 0.3;
    DisPuOutput after = model.forward(x, params, NormStatistics::kBatch);
    EXPECT_TRUE(after.coarse.equal(before.coarse));
    EXPECT_GT((after.fine - before.fine).abs().max().item<double>(), 1e-4);
}

TEST(DisPu, PermutingInputPointsPermutesEveryCopy) {
    DisPu model = make({{"preset", "compact"}, {"seed", 5}});
    at::Tensor x = test::sheet(1, 64, 5);
    at::Generator gen = at::detail::createCPUGenerator(6);
    at::Tensor perm = at::randperm(64, gen, at::TensorOptions().dtype(at::kLong));
    at::NoGradGuard no_grad;
    for (NormStatistics statistics : {NormStatistics::kRunning, NormStatistics::kBatch}) {
        at::Tensor y = model.forward(x, model.parameters(), statistics).fine.view({1, 4, 64, 3});
        at::Tensor y_perm = model.forward(x.index_select(1, perm), model.parameters(), statistics)
                                .fine.view({1, 4, 64, 3});
        EXPECT_TRUE(at::allclose(y_perm, y.index_select(2, perm), 1e-4, 1e-5));
    }
}

TEST(DisPu, FineWeightScheduleSwitchesAfterEpochs10And20And30) {
    // TensorFlow's piecewise_constant on the completed-epoch counter: 0.01 while epoch <= 10.
    for (auto [step, expected] : std::vector<std::pair<int64_t, double>>{{-5, 0.01},
                                                                         {0, 0.01},
                                                                         {109, 0.01},
                                                                         {110, 0.1},
                                                                         {209, 0.1},
                                                                         {210, 0.5},
                                                                         {309, 0.5},
                                                                         {310, 1.0},
                                                                         {100000, 1.0}})
        EXPECT_EQ(dispu_fine_weight(step, 10), expected) << "step " << step;
    EXPECT_THROW(dispu_fine_weight(0, 0), InputError);
}

TEST(DisPu, LossCombinesCoarseFineAndRepulsionTermsWithTheSchedule) {
    nlohmann::json config = tiny_dispu_config();
    config["steps_per_epoch"] = 1;
    config["repulsion_weight"] = 2.0;
    DisPu model = make(config);
    at::Tensor input = test::sheet(2, 16, 7);
    at::Tensor target = test::sheet(2, 64, 8);
    auto expected = [&](double w) {
        DisPuOutput out = model.forward(input, model.parameters(), NormStatistics::kBatch);
        return 2000 * chamfer_loss(out.coarse, target).item<double>() +
               w * 2000 * chamfer_loss(out.fine, target).item<double>() +
               2.0 * repulsion_loss(out.fine).item<double>();
    };
    EXPECT_NEAR(model.loss(input, target, model.parameters(), 0).item<double>(), expected(0.01),
                1e-4 * expected(0.01));
    EXPECT_NEAR(model.loss(input, target, model.parameters(), 40).item<double>(), expected(1.0),
                1e-4 * expected(1.0));
    // The same loss term by term, for the training log.
    auto terms = model.loss_terms(input, target, model.parameters(), 40);
    ASSERT_EQ(terms.size(), 3u);
    EXPECT_EQ(terms[0].first, "coarse");
    EXPECT_EQ(terms[1].first, "fine");
    EXPECT_EQ(terms[2].first, "repulsion");
    DisPuOutput out = model.forward(input, model.parameters(), NormStatistics::kBatch);
    EXPECT_NEAR(terms[1].second.item<double>(),
                2000 * chamfer_loss(out.fine, target).item<double>(), 1e-4 * expected(1.0));
    EXPECT_NEAR(terms[2].second.item<double>(), 2.0 * repulsion_loss(out.fine).item<double>(),
                1e-4 * expected(1.0));
    // After 12 pretraining steps the schedule continues from step 11 (epoch 11: w = 0.1) for
    // callers that pass no step, as meta-learning does.
    for (int i = 0; i < 12; ++i) model.update_buffers(input, model.parameters());
    EXPECT_EQ(model.pretrain_steps(), 12);
    EXPECT_NEAR(model.loss(input, target, model.parameters()).item<double>(), expected(0.1),
                1e-4 * expected(0.1));
}

TEST(DisPu, CompactModelOverfitsOnePatch) {
    DisPu model = make({{"preset", "compact"}, {"steps_per_epoch", 1}, {"seed", 2}});
    at::Tensor dense = test::sheet(1, 256, 9);
    at::Tensor input = dense.narrow(1, 0, 64);
    Adam adam(model.parameters(), AdamOptions{1e-3});
    const int64_t step = 100;  // fine weight 1
    double first = model.loss(input, dense, model.parameters(), step).item<double>();
    double last = first;
    for (int i = 0; i < 50; ++i) {
        at::Tensor loss = model.loss(input, dense, model.parameters(), step);
        last = loss.item<double>();
        adam.step(gradients(loss, model.parameters()));
    }
    EXPECT_LE(last, 0.5 * first) << "first " << first;
}

TEST(DisPu, BatchNormBuffersChangeOnlyThroughUpdateBuffers) {
    DisPu model = make(tiny_dispu_config());
    at::Tensor x = test::sheet(2, 16, 14);
    at::Tensor y = test::sheet(2, 64, 15);
    ParamMap before = snapshot(model.buffers());
    at::Tensor plain = model.upsample(x).detach();

    // Training loss, its gradients, test-time adaptation and inference leave buffers alone.
    gradients(model.loss(x, y, model.parameters()), model.parameters());
    MetaOptions options;
    options.inner_steps = 2;
    options.inner_lr = 1e-4;
    adapt(model, model.parameters(), model.downsample(x, 1), x, options.inner_loop(), {}, false);
    meta_gradient(model, x, y, options, {}, 2);
    EXPECT_TRUE(same(model.buffers(), before));

    // update_buffers: running stats move by momentum 0.05 towards the weight net's
    // pre-normalisation batch statistics, recomputed here with a brute-force kNN.
    model.update_buffers(x, model.parameters());
    EXPECT_EQ(model.pretrain_steps(), 1);
    at::NoGradGuard no_grad;
    at::Tensor coarse = model.forward(x, model.parameters(), NormStatistics::kBatch).coarse;
    at::Tensor sq = (coarse.unsqueeze(2) - coarse.unsqueeze(1)).pow(2).sum(-1);  // [B,M,M]
    at::Tensor group = sq.argsort(/*dim=*/int64_t{-1}).narrow(-1, 0, 4);         // self first
    at::Tensor members = coarse.unsqueeze(1)
                             .expand({-1, 64, -1, -1})
                             .gather(2, group.unsqueeze(-1).expand({-1, -1, -1, 3}));
    at::Tensor rel = (members - coarse.unsqueeze(2)).reshape({-1, 3});
    at::Tensor pre = at::addmm(model.parameters().at("refine.weight_net.conv.bias"), rel,
                               model.parameters().at("refine.weight_net.conv.weight").t());
    EXPECT_TRUE(at::allclose(model.buffers().at("refine.weight_net.bn.running_mean"),
                             0.05 * pre.mean(0), 1e-5, 1e-6));
    EXPECT_TRUE(at::allclose(model.buffers().at("refine.weight_net.bn.running_var"),
                             0.95 + 0.05 * pre.var(0, /*unbiased=*/true), 1e-5, 1e-6));

    // Inference uses the running statistics; the loss does not.
    EXPECT_FALSE(model.upsample(x).equal(plain));
    ParamMap updated = snapshot(model.buffers());
    model.buffers() = before;
    double loss_before = model.loss(x, y, model.parameters()).item<double>();
    model.buffers() = updated;
    // Same pretrain_steps - 1 = 0 schedule position, so the same loss.
    EXPECT_EQ(model.loss(x, y, model.parameters()).item<double>(), loss_before);
}

TEST(DisPu, CheckpointAndTrainingStateRoundTripIncludingBuffers) {
    test::TempDir dir;
    DisPu model = make(tiny_dispu_config());
    at::Tensor x = test::sheet(2, 16, 16);
    for (int i = 0; i < 3; ++i) model.update_buffers(x, model.parameters());
    {
        at::NoGradGuard no_grad;
        for (auto& [name, p] : model.parameters()) p.add_(0.01);
    }
    save_checkpoint(dir.file("m.pt"), model, {{"step", 3}});
    LoadedCheckpoint loaded = load_checkpoint(dir.file("m.pt"));
    EXPECT_TRUE(same(loaded.backbone->buffers(), model.buffers()));
    EXPECT_TRUE(same(snapshot(loaded.backbone->parameters()), snapshot(model.parameters())));
    EXPECT_EQ(dynamic_cast<DisPu&>(*loaded.backbone).pretrain_steps(), 3);
    at::NoGradGuard no_grad;
    EXPECT_TRUE(loaded.backbone->upsample(x).equal(model.upsample(x)));

    ParamMap optimizer = {{"m/features.layer0.weight", at::ones({4, 3})}};
    save_training_state(dir.file("state.ckpt"), model, optimizer, {{"step", 3}});
    TrainingState state = load_training_state(dir.file("state.ckpt"));
    EXPECT_TRUE(same(state.model->buffers(), model.buffers()));
    EXPECT_TRUE(state.model->upsample(x).equal(model.upsample(x)));
    EXPECT_TRUE(same(state.optimizer, optimizer));
}

TEST(DisPu, CheckpointsWithMissingOrForeignBuffersAreInputErrors) {
    test::TempDir dir;
    auto error_after = [&](auto edit) -> std::string {
        DisPu model = make(tiny_dispu_config());
        edit(model.buffers());
        save_checkpoint(dir.file("m.pt"), model);
        try {
            load_checkpoint(dir.file("m.pt"));
        } catch (const InputError& e) {
            return e.what();
        }
        return "no error";
    };
    auto contains = [](const std::string& text, const std::string& part) {
        return text.find(part) != std::string::npos;
    };
    EXPECT_TRUE(contains(error_after([](ParamMap& b) { b.erase("schedule.pretrain_steps"); }),
                         "lacks buffer 'schedule.pretrain_steps' of backbone dispu"));
    EXPECT_TRUE(contains(error_after([](ParamMap& b) { b["stray"] = at::zeros({1}); }),
                         "tensor 'buffers/stray' does not belong to backbone dispu"));
    EXPECT_TRUE(contains(
        error_after([](ParamMap& b) { b["refine.weight_net.bn.running_var"] = at::ones({3}); }),
        "buffer 'refine.weight_net.bn.running_var' has shape [3]"));
}

TEST(DisPu, WholeCloudUpsamplingGivesExactlyRatioTimesInputPoints) {
    at::Tensor cloud = uniform_random_points(300, 17);
    cloud = cloud / cloud.norm(2, 1, true);  // a sphere: a surface to cut patches from
    std::unique_ptr<Backbone> x4 = make_backbone(tiny_dispu_config(4));
    std::unique_ptr<Backbone> x8 = make_backbone(tiny_dispu_config(8));
    for (auto [model, ratio] :
         std::vector<std::pair<Backbone*, int64_t>>{{x4.get(), 4}, {x4.get(), 16}, {x8.get(), 8}}) {
        UpsampleOptions options;
        options.ratio = ratio;
        UpsampleResult result = upsample_cloud(*model, cloud, options);
        EXPECT_EQ(result.points.sizes(), (std::vector<int64_t>{300 * ratio, 3})) << ratio;
        EXPECT_TRUE(result.points.isfinite().all().item<bool>());
    }
    // Inputs smaller than k and than a patch, and test-time adaptation (buffers untouched).
    EXPECT_EQ(upsample_cloud(*x4, cloud.narrow(0, 0, 3), {}).points.size(0), 12);
    ParamMap buffers = snapshot(x4->buffers());
    UpsampleOptions tta;
    tta.adaptation.inner.steps = 2;
    tta.adaptation.inner.step_size = 1e-4;
    UpsampleResult adapted = upsample_cloud(*x4, cloud, tta);
    EXPECT_EQ(adapted.points.size(0), 1200);
    EXPECT_TRUE(std::isfinite(adapted.loss_after));
    EXPECT_TRUE(same(x4->buffers(), buffers));
}

TEST(DisPu, ConfigPresetsRoundTripAndRebuildTheSameWeights) {
    DisPuOptions paper = DisPuOptions::from_json(nlohmann::json::object());
    EXPECT_EQ(paper.preset, "paper");
    EXPECT_EQ(paper.downsampler, "nonuniform");
    EXPECT_EQ(paper.k, 16);
    EXPECT_EQ(paper.growth, 24);
    DisPuOptions compact = DisPuOptions::from_json({{"preset", "compact"}, {"ratio", 8}});
    EXPECT_EQ(compact.growth, 12);
    EXPECT_EQ(compact.refiner_channels, 64);
    EXPECT_EQ(compact.ratio, 8);
    // Explicit fields override the preset, whatever their order in the object.
    EXPECT_EQ(DisPuOptions::from_json({{"growth", 6}, {"preset", "compact"}}).growth, 6);

    DisPu model = make({{"preset", "compact"}, {"seed", 9}, {"downsampler", "fps"}});
    nlohmann::json config = model.config();
    EXPECT_EQ(config["backbone"], "dispu");
    EXPECT_EQ(config["preset"], "compact");
    std::unique_ptr<Backbone> again = make_backbone(config);
    EXPECT_EQ(again->config(), config);
    EXPECT_TRUE(same(snapshot(again->parameters()), snapshot(model.parameters())));
    config["seed"] = 10;
    EXPECT_FALSE(make_backbone(config)
                     ->parameters()
                     .at("features.layer0.weight")
                     .equal(model.parameters().at("features.layer0.weight")));
}

TEST(DisPu, ShippedTrainingConfigBuildsTheCompactModel) {
    nlohmann::json j =
        nlohmann::json::parse(test::read_file(test::source_dir() + "/configs/dispu-x4.json"));
    TrainConfig config = TrainConfig::from_json(j);
    EXPECT_EQ(config.train_data, "data/dataset/train-x4.tensors");
    EXPECT_EQ(config.val_data, "data/dataset/val-x4.tensors");
    EXPECT_EQ(config.run_dir, "runs/dispu-x4");
    std::unique_ptr<Backbone> model = make_backbone(config.backbone);
    EXPECT_EQ(model->name(), "dispu");
    EXPECT_EQ(model->ratio(), 4);
    EXPECT_EQ(model->config()["preset"], "compact");
    EXPECT_EQ(count_parameters(model->parameters()), 263374);
}

TEST(DisPu, InvalidConfigsAreInputErrorsNamingTheField) {
    auto message = [](const nlohmann::json& config) -> std::string {
        try {
            make_backbone(config);
        } catch (const InputError& e) {
            return e.what();
        }
        return "no error";
    };
    auto has = [&](const nlohmann::json& config, const std::string& part) {
        return message(config).find(part) != std::string::npos;
    };
    EXPECT_TRUE(has({{"backbone", "dispu"}, {"grwth", 8}}, "unknown field 'grwth'"));
    EXPECT_TRUE(has({{"backbone", "dispu"}, {"preset", "huge"}}, "unknown preset 'huge'"));
    EXPECT_TRUE(has({{"backbone", "dispu"}, {"k", 0}}, "'k'"));
    EXPECT_TRUE(has({{"backbone", "dispu"}, {"steps_per_epoch", -3}}, "'steps_per_epoch'"));
    EXPECT_TRUE(has({{"backbone", "dispu"}, {"downsampler", "grid"}}, "grid"));
    EXPECT_TRUE(has({{"backbone", "dispu"}, {"repulsion_weight", -1}}, "repulsion_weight"));
    EXPECT_TRUE(has({{"backbone", "dispu"}, {"patch_size", 1}}, "patch_size"));
    EXPECT_TRUE(has({{"backbone", "dispu"}, {"coarse_residual", 1}}, "coarse_residual"));
}

TEST(DisPu, TooFewPointsOrWrongTypesAreInputErrors) {
    DisPu model = make(tiny_dispu_config());
    EXPECT_THROW(model.upsample(test::sheet(1, 1, 1)), InputError);
    EXPECT_THROW(model.upsample(test::sheet(1, 16, 1, at::kDouble)), InputError);
    EXPECT_THROW(model.upsample(at::zeros({1, 16, 2})), InputError);
    EXPECT_THROW(model.update_buffers(at::zeros({16, 3}), model.parameters()), InputError);
}

}  // namespace pumeta
