// PU-GAN: parameter counts against the original's layer list, the copy-major grid, the
// up-down-up shapes, the farthest-point reduction, the attention scales, the losses
// (reconstruction, training terms, discriminator) and a training run whose discriminator
// stays out of the model file.
#include "pumeta/models/pugan.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/nn/emd_loss.h"
#include "pumeta/nn/gradients.h"
#include "pumeta/nn/repulsion_loss.h"
#include "pumeta/nn/uniform_loss.h"
#include "pumeta/train/trainer.h"
#include "pumeta/train/training_state.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

PuGan make(const nlohmann::json& config) { return PuGan(PuGanOptions::from_json(config)); }

nlohmann::json small(int64_t ratio = 4) {
    nlohmann::json config = pugan_small_config();
    config["ratio"] = ratio;
    return config;
}

int64_t conv(int64_t in, int64_t out) { return in * out + out; }

// The generator's trainable variables from the original's layer list (generator.py, ops.py:
// feature_extraction, up_projection_unit, up_block, down_block, attention_unit, fc_layer1/2)
// at the paper's widths, written independently of the model's construction.
int64_t original_generator_count(int64_t copies) {
    int64_t total = conv(3, 24);  // layer0
    int64_t channels = 24;
    for (int64_t b = 0; b < 4; ++b) {
        int64_t in = 24;
        if (b > 0) {
            total += conv(channels, 48);  // layer<b>_prep
            in = 48;
        }
        total += conv(2 * in, 24) + conv(24 + in, 24) + conv(48 + in, 24);  // dense_conv
        channels = (b == 0 ? 24 : channels) + 72 + in;
    }
    EXPECT_EQ(channels, 480);
    const int64_t attention = 2 * conv(130, 32) + conv(130, 130) + 1;  // f, g, h, gamma
    const int64_t up = attention + conv(130, 256) + conv(256, 128);
    const int64_t down = conv(copies * 128, 256) + conv(256, 128);
    return total + conv(480, 128) + 2 * up + down + conv(128, 64) + conv(64, 3);
}

TEST(PuGan, PaperWidthHasTheOriginalsParameterCounts) {
    PuGan model = make({{"backbone", "pugan"}});
    EXPECT_EQ(model.options().copies(), 6);
    EXPECT_EQ(original_generator_count(6), 541601);
    EXPECT_EQ(count_parameters(model.parameters()), 541601);
    // The discriminator: 2,240 + 24,769 + 49,536 + 66,049.
    EXPECT_EQ(count_parameters(model.make_auxiliary(1)), 142594);
    // 8×: r' = 10 widens only the down block's [1, r'] convolution.
    PuGan x8 = make({{"backbone", "pugan"}, {"ratio", 8}});
    EXPECT_EQ(count_parameters(x8.parameters()), original_generator_count(10));
    EXPECT_EQ(count_parameters(x8.parameters()), 541601 + 4 * 128 * 256);
    EXPECT_EQ(count_parameters(x8.make_auxiliary(1)), 142594);
}

TEST(PuGan, GridCodesAreCopyMajor) {
    at::Tensor features = at::tensor({10.0f, 20.0f}).view({1, 2, 1});
    at::Tensor tiled = pugan_tile_with_grid(features, 6)[0];  // [12, 3]
    ASSERT_EQ(tiled.sizes(), (std::vector<int64_t>{12, 3}));
    const float xs[3] = {-0.2f, 0.0f, 0.2f}, ys[2] = {-0.2f, 0.2f};
    for (int64_t c = 0; c < 6; ++c) {
        for (int64_t n = 0; n < 2; ++n) {
            at::Tensor row = tiled[c * 2 + n];
            EXPECT_EQ(row[0].item<float>(), n == 0 ? 10.0f : 20.0f) << c << "," << n;
            EXPECT_NEAR(row[1].item<float>(), xs[c % 3], 1e-7) << c;
            EXPECT_NEAR(row[2].item<float>(), ys[c / 3], 1e-7) << c;
        }
    }
    // r' = 10: 2 × 5 (the largest divisor of 10 not above ⌊√10⌋ + 1 = 4 is 2).
    at::Tensor ten = pugan_tile_with_grid(at::zeros({1, 1, 1}), 10)[0];
    EXPECT_NEAR(ten[1][1].item<float>(), 0.2f, 1e-7);   // copy 1: x_1
    EXPECT_NEAR(ten[2][2].item<float>(), -0.1f, 1e-7);  // copy 2: y_1 of 5 in [−0.2, 0.2]
}

TEST(PuGan, OutputsRNOfTheRPrimeNPointsByFarthestPointSampling) {
    for (int64_t ratio : {4, 8}) {
        PuGan model = make(small(ratio));
        at::NoGradGuard no_grad;
        at::Tensor x = test::sheet(2, 16, 1);
        at::Tensor dense = model.generate(x, model.parameters());
        EXPECT_EQ(dense.sizes(), (std::vector<int64_t>{2, (ratio + 2) * 16, 3}));
        at::Tensor out = model.upsample(x);
        ASSERT_EQ(out.sizes(), (std::vector<int64_t>{2, ratio * 16, 3}));
        for (int64_t b = 0; b < 2; ++b) {
            at::Tensor picked = farthest_point_sampling(dense[b].contiguous(), ratio * 16);
            EXPECT_TRUE(out[b].equal(dense[b].index_select(0, picked))) << ratio << ", " << b;
        }
    }
}

TEST(PuGan, AttentionScalesStartAtZeroSoTheirBranchesStartSilent) {
    PuGan model = make(small());
    for (const char* name : {"up0.attention.gamma", "up1.attention.gamma"})
        EXPECT_EQ(model.parameters().at(name).item<float>(), 0.0f) << name;
    EXPECT_EQ(model.make_auxiliary(2).at("d.attention.gamma").item<float>(), 0.0f);

    at::Tensor y = test::sheet(2, 64, 3);
    at::Tensor x = model.downsample(y, 4);
    ParamMap grads = gradients(model.loss(x, y, model.parameters()), model.parameters());
    EXPECT_EQ(grads.at("up0.attention.f.weight").abs().max().item<float>(), 0.0f);
    EXPECT_GT(grads.at("up0.attention.gamma").abs().item<float>(), 0.0f);
    // With γ ≠ 0 the attention's own weights learn.
    ParamMap moved = model.parameters();
    moved["up0.attention.gamma"] = at::full({1}, 0.5).requires_grad_(true);
    grads = gradients(model.loss(x, y, moved), moved);
    EXPECT_GT(grads.at("up0.attention.f.weight").abs().max().item<float>(), 0.0f);
}

TEST(PuGan, ReconstructionLossIsWeightedEmdUniformityAndRepulsion) {
    PuGan model = make(small());
    at::Tensor y = test::sheet(2, 64, 5);
    at::Tensor x = model.downsample(y, 6);
    LossTerms terms = model.loss_terms(x, y, model.parameters());
    ASSERT_EQ(terms.size(), 3u);
    at::NoGradGuard no_grad;
    at::Tensor pred = model.upsample(x);
    EXPECT_EQ(terms[0].first, "emd");
    EXPECT_NEAR(terms[0].second.item<double>(), 100 * emd_loss(pred, y).item<double>(), 1e-5);
    EXPECT_EQ(terms[1].first, "uniform");
    EXPECT_NEAR(terms[1].second.item<double>(), 10 * uniform_loss(pred).item<double>(), 1e-6);
    EXPECT_EQ(terms[2].first, "repulsion");
    EXPECT_NEAR(terms[2].second.item<double>(), repulsion_loss(pred).item<double>(), 1e-7);
    EXPECT_NEAR(model.loss(x, y, model.parameters()).item<double>(), sum_of(terms).item<double>(),
                1e-5);
    EXPECT_TRUE(test::throws_input_error(
        [&] { model.loss(x, y.narrow(1, 0, 60), model.parameters()); }, {"pugan loss"}));
}

TEST(PuGan, TrainingTermsAddTheRegulariserAndTheAdversarialTerm) {
    PuGan model = make(small());
    ParamMap d = model.make_auxiliary(7);
    at::Tensor y = test::sheet(2, 64, 8);
    at::Tensor x = model.downsample(y, 9);
    LossTerms terms = model.training_terms(x, y, model.parameters(), d, 0);
    ASSERT_EQ(terms.size(), 5u);
    EXPECT_EQ(terms[3].first, "regularization");
    EXPECT_EQ(terms[4].first, "adversarial");
    double squares = 0;
    for (const auto& [name, p] : model.parameters())
        if (name.rfind("fc2.", 0) != 0 && name.find("gamma") == std::string::npos)
            squares += p.detach().to(at::kDouble).pow(2).sum().item<double>();
    EXPECT_NEAR(terms[3].second.item<double>(), 0.5e-5 * squares, 1e-9);
    at::NoGradGuard no_grad;
    const double score =
        pugan_discriminate(model.upsample(x), d).sub(1).pow(2).mean().item<double>();
    EXPECT_NEAR(terms[4].second.item<double>(), 0.5 * score, 1e-6);
    EXPECT_EQ(pugan_discriminate(y, d).sizes(), (std::vector<int64_t>{2}));
}

// A reconstruction-only run (adversarial_weight 0) has no discriminator to train and no
// adversarial term; the rest of its training terms are those of the full loss.
TEST(PuGan, WithoutTheAdversarialTermThereIsNoDiscriminator) {
    nlohmann::json config = small();
    config["adversarial_weight"] = 0.0;
    PuGan plain = make(config);
    PuGan full = make(small());
    EXPECT_TRUE(plain.make_auxiliary(7).empty());
    at::Tensor y = test::sheet(2, 64, 8);
    at::Tensor x = plain.downsample(y, 9);
    LossTerms terms = plain.training_terms(x, y, plain.parameters(), {}, 0);
    LossTerms reference = full.training_terms(x, y, full.parameters(), full.make_auxiliary(7), 0);
    ASSERT_EQ(terms.size(), reference.size() - 1);
    for (size_t i = 0; i < terms.size(); ++i) {
        EXPECT_EQ(terms[i].first, reference[i].first);
        EXPECT_TRUE(at::equal(terms[i].second, reference[i].second)) << terms[i].first;
    }
}

TEST(PuGan, DiscriminatorLossIsLsganAndReachesOnlyTheDiscriminator) {
    PuGan model = make(small());
    ParamMap d = model.make_auxiliary(10);
    at::Tensor y = test::sheet(2, 64, 11);
    at::Tensor x = model.downsample(y, 12);
    at::Tensor loss = model.auxiliary_loss(x, y, model.parameters(), d, 0);
    {
        at::NoGradGuard no_grad;
        const double expected =
            pugan_discriminate(y, d).sub(1).pow(2).mean().item<double>() +
            pugan_discriminate(model.upsample(x), d).pow(2).mean().item<double>();
        EXPECT_NEAR(loss.item<double>(), expected, 1e-6);
    }
    ParamMap grads = gradients(loss, d);
    EXPECT_GT(grads.at("d.fc1.weight").abs().max().item<float>(), 0.0f);
    model.auxiliary_loss(x, y, model.parameters(), d, 0).backward();
    for (const auto& [name, p] : model.parameters()) EXPECT_FALSE(p.grad().defined()) << name;
    // Same seed, same discriminator.
    EXPECT_TRUE(model.make_auxiliary(10).at("d.conv0.weight").equal(d.at("d.conv0.weight")));
    EXPECT_FALSE(model.make_auxiliary(11).at("d.conv0.weight").equal(d.at("d.conv0.weight")));
}

TEST(PuGan, DiscriminatorStepReusesTheGeneratorOutputOfItsBatch) {
    PuGan model = make(small());
    ParamMap d = model.make_auxiliary(13);
    at::Tensor y = test::sheet(2, 64, 14);
    at::Tensor x = model.downsample(y, 15);
    auto fake_score = [&](const at::Tensor& fake) {
        at::NoGradGuard no_grad;
        return pugan_discriminate(y, d).sub(1).pow(2).mean().item<double>() +
               pugan_discriminate(fake, d).pow(2).mean().item<double>();
    };
    at::Tensor before;
    {
        at::NoGradGuard no_grad;
        before = model.upsample(x);
    }
    model.training_terms(x, y, model.parameters(), d, 0);
    {
        at::NoGradGuard no_grad;  // the generator's update between the two calls
        for (auto& [name, p] : model.parameters()) p.add_(0.05);
    }
    at::Tensor after;
    {
        at::NoGradGuard no_grad;
        after = model.upsample(x);
    }
    ASSERT_GT(std::abs(fake_score(before) - fake_score(after)), 1e-6)
        << "the update changes D's input";
    // The same batch: the output from before the update, as the original's D-first order.
    EXPECT_NEAR(model.auxiliary_loss(x, y, model.parameters(), d, 0).item<double>(),
                fake_score(before), 1e-6);
    // Used once: a second call, or another input tensor, upsamples with the current weights.
    EXPECT_NEAR(model.auxiliary_loss(x, y, model.parameters(), d, 0).item<double>(),
                fake_score(after), 1e-6);
    model.training_terms(x, y, model.parameters(), d, 0);
    EXPECT_NEAR(model.auxiliary_loss(x.clone(), y, model.parameters(), d, 0).item<double>(),
                fake_score(after), 1e-6);

    // Two generator updates on one batch (updates_per_batch 2): D still sees the output from
    // before the first, as the original's D step, which precedes both.
    model.training_terms(x, y, model.parameters(), d, 0);
    {
        at::NoGradGuard no_grad;
        for (auto& [name, p] : model.parameters()) p.add_(0.05);
    }
    model.training_terms(x, y, model.parameters(), d, 0);
    EXPECT_NEAR(model.auxiliary_loss(x, y, model.parameters(), d, 0).item<double>(),
                fake_score(after), 1e-6);
}

TEST(PuGan, TrainsWithItsDiscriminatorKeptInTheRunStateOnly) {
    test::TempDir dir;
    PatchSet set;
    set.ratio = 4;
    set.patch_points = 16;
    set.points = uniform_random_points(400, 5);
    set.offsets = at::tensor({int64_t{0}, int64_t{200}, int64_t{400}});
    std::vector<int64_t> seeds;
    for (int64_t mesh = 0; mesh < 2; ++mesh)
        for (int64_t i = 0; i < 6; ++i) seeds.insert(seeds.end(), {mesh, i * 31});
    set.seeds = at::tensor(seeds).view({12, 2});
    set.ids = {"a", "b"};
    save_patch_set(dir.file("train.tensors"), set);

    TrainConfig config;
    config.backbone = small();
    config.train_data = dir.file("train.tensors");
    config.run_dir = dir.file("run");
    config.batch_size = 2;
    config.steps = 2;
    config.log_every = 1;
    train(config, false);

    std::vector<nlohmann::json> steps = test::log_records(dir.file("run/log.jsonl"), "loss");
    EXPECT_EQ(steps.size(), 2u);
    for (const nlohmann::json& j : steps)
        for (const char* term : {"loss_emd", "loss_uniform", "loss_repulsion",
                                 "loss_regularization", "loss_adversarial", "auxiliary_loss"})
            EXPECT_TRUE(j.contains(term)) << term << " missing from " << j.dump();
    TrainingState state = load_training_state(dir.file("run/state.ckpt"));
    ParamMap fresh = make(small()).make_auxiliary(config.seed);
    ASSERT_TRUE(state.optimizer.count("aux/d.fc1.weight"));
    EXPECT_FALSE(state.optimizer.at("aux/d.fc1.weight").equal(fresh.at("d.fc1.weight")));
    LoadedCheckpoint shipped = load_checkpoint(dir.file("run/model.pt"));
    EXPECT_EQ(shipped.backbone->parameters().size(), make(small()).parameters().size());
    for (const auto& [name, p] : shipped.backbone->parameters())
        EXPECT_NE(name.rfind("d.", 0), 0u) << name;
}

TEST(PuGan, ConfigRoundTripsAndRejectsBadFields) {
    PuGanOptions compact = PuGanOptions::from_json({{"backbone", "pugan"}, {"preset", "compact"}});
    EXPECT_EQ(compact.feature_channels, 64);
    EXPECT_EQ(PuGanOptions::from_json(compact.to_json()).to_json(), compact.to_json());
    PuGanOptions defaults = PuGanOptions::from_json({{"backbone", "pugan"}});
    EXPECT_EQ(defaults.downsampler, "nonuniform");
    EXPECT_EQ(defaults.emd_matching, "auction");
    EXPECT_TRUE(test::throws_input_error(
        [] {
            PuGanOptions::from_json({{"colour", 1}});
        },
        {"pugan config", "unknown field 'colour'"}));
    EXPECT_TRUE(test::throws_input_error(
        [] {
            PuGanOptions::from_json({{"preset", "huge"}});
        },
        {"unknown preset"}));
    EXPECT_TRUE(test::throws_input_error(
        [] {
            PuGanOptions::from_json({{"emd_matching", "exact"}});
        },
        {"emd_matching"}));
    EXPECT_TRUE(test::throws_input_error(
        [] {
            PuGanOptions::from_json({{"extra_copies", -1}});
        },
        {"extra_copies"}));
}

}  // namespace
}  // namespace pumeta
