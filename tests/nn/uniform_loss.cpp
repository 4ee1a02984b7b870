// Uniformity loss: a hand-computed value on a tiny cloud (with and without padding),
// orderings on clouds of known uniformity, the two spacings, gradients of both orders against
// finite differences, and input errors.
#include "pumeta/nn/uniform_loss.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <cmath>
#include <vector>

#include "pumeta/core/error.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

const double kPi = std::acos(-1.0);

/// 20 points: p0 at the origin, p1 at (0.1, 0, 0), the rest on a far line (x >= 1). FPS with
/// one seed picks p0.
at::Tensor tiny_cloud(double second_x) {
    std::vector<double> xyz = {0, 0, 0, second_x, 0, 0};
    for (int i = 2; i < 20; ++i) xyz.insert(xyz.end(), {1.0 + 0.1 * i, 0.05 * i, 0});
    return at::tensor(xyz, at::kDouble).view({1, 20, 3});
}

UniformLossOptions one_disk(double p) {
    UniformLossOptions options;
    options.percentages = {p};
    options.seed_fraction = 0.05;  // ⌊20 · 0.05⌋ = 1 seed
    return options;
}

TEST(UniformLoss, HandComputedOnATinyCloud) {
    // p = 0.1: n_p = 2, radius 0.316; members p0 and p1, each other's nearest at 0.1.
    const double d = std::sqrt(0.01 + 1e-8);
    const double expected_spacing = std::sqrt(kPi * 0.1 / 2);
    const double term = std::pow(d - expected_spacing, 2) / (expected_spacing + 1e-8) * 100;
    EXPECT_NEAR(uniform_loss(tiny_cloud(0.1), one_disk(0.1)).item<double>(), term, 1e-12);

    // Hexagonal spacing: d̂ = √(2π p / (√3 n)).
    UniformLossOptions hex = one_disk(0.1);
    hex.spacing = UniformSpacing::kHexagonal;
    const double hex_spacing = std::sqrt(2 * kPi * 0.1 / (std::sqrt(3.0) * 2));
    EXPECT_NEAR(uniform_loss(tiny_cloud(0.1), hex).item<double>(),
                std::pow(d - hex_spacing, 2) / (hex_spacing + 1e-8) * 100, 1e-12);
}

TEST(UniformLoss, MissingMembersArePaddedWithTheFirstHit) {
    // p = 0.15: n_p = 3 but only p0 and p1 lie within 0.387: members p0, p1, p0. p0 and its
    // copy are each other's nearest (d = 1e-4), p1's nearest is p0 (0.1).
    const double p = 0.15, spacing = std::sqrt(kPi * p / 3);
    auto term = [&](double d) { return std::pow(d - spacing, 2) / (spacing + 1e-8); };
    const double expected =
        (2 * term(std::sqrt(1e-8)) + term(std::sqrt(0.01 + 1e-8))) / 3 * std::pow(100 * p, 2);
    EXPECT_NEAR(uniform_loss(tiny_cloud(0.1), one_disk(p)).item<double>(), expected, 1e-12);
}

TEST(UniformLoss, OnlyTheFirstPointsInIndexOrderCount) {
    // The members' spacing sets the loss: p1 at 0.05 and at 0.2 from p0 differ.
    at::Tensor near = tiny_cloud(0.05), far = tiny_cloud(0.2);
    EXPECT_NE(uniform_loss(near, one_disk(0.1)).item<double>(),
              uniform_loss(far, one_disk(0.1)).item<double>());
    // A point inside the disk after the first n_p changes nothing.
    at::Tensor extra = tiny_cloud(0.1).clone();
    extra[0][5] = at::tensor({0.0, 0.05, 0.0}, at::kDouble);
    EXPECT_DOUBLE_EQ(uniform_loss(extra, one_disk(0.1)).item<double>(),
                     uniform_loss(tiny_cloud(0.1), one_disk(0.1)).item<double>());
}

/// 1024 points on a regular 32 × 32 square lattice spanning the unit disk's inscribed square.
at::Tensor lattice() {
    at::Tensor t = at::linspace(-0.7, 0.7, 32, at::kDouble);
    std::vector<at::Tensor> grid = at::meshgrid({t, t}, "ij");
    return at::stack({grid[0].reshape(-1), grid[1].reshape(-1), at::zeros({1024}, at::kDouble)}, 1)
        .unsqueeze(0);
}

/// The same count of points in 8 tight clumps.
at::Tensor clustered(uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::Tensor centres = 0.6 * (2 * at::rand({8, 1, 3}, gen, at::kDouble) - 1);
    centres.select(2, 2).zero_();
    at::Tensor offsets = 0.03 * at::randn({8, 128, 3}, gen, at::kDouble);
    offsets.select(2, 2).zero_();
    return (centres + offsets).reshape({1, 1024, 3});
}

at::Tensor random_square(uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::Tensor xyz = 1.4 * at::rand({1, 1024, 3}, gen, at::kDouble) - 0.7;
    xyz.select(2, 2).zero_();
    return xyz;
}

TEST(UniformLoss, ALatticeScoresLowerThanRandomPointsAndRandomLowerThanClumps) {
    const double regular = uniform_loss(lattice()).item<double>();
    const double random = uniform_loss(random_square(3)).item<double>();
    const double clumps = uniform_loss(clustered(4)).item<double>();
    EXPECT_LT(regular, random);
    EXPECT_LT(random, clumps);
    // The same order under Meta-PU's settings.
    UniformLossOptions metapu = metapu_uniform_options();
    EXPECT_LT(uniform_loss(lattice(), metapu).item<double>(),
              uniform_loss(clustered(4), metapu).item<double>());
}

TEST(UniformLoss, SettingsOfTheTwoNetworks) {
    UniformLossOptions pugan = pugan_uniform_options();
    EXPECT_EQ(pugan.percentages, (std::vector<double>{0.004, 0.006, 0.008, 0.010, 0.012}));
    EXPECT_EQ(pugan.spacing, UniformSpacing::kSquare);
    EXPECT_DOUBLE_EQ(pugan.seed_fraction, 0.05);
    UniformLossOptions metapu = metapu_uniform_options();
    EXPECT_EQ(metapu.percentages, (std::vector<double>{0.004, 0.008, 0.010, 0.012, 0.016}));
    EXPECT_EQ(metapu.spacing, UniformSpacing::kHexagonal);
}

TEST(UniformLoss, BatchElementsAverageAndFloatMatchesDouble) {
    at::Tensor a = random_square(5), b = clustered(6);
    const double both = uniform_loss(at::cat({a, b})).item<double>();
    EXPECT_NEAR(both, 0.5 * (uniform_loss(a).item<double>() + uniform_loss(b).item<double>()),
                1e-12);
    EXPECT_NEAR(uniform_loss(a.to(at::kFloat)).item<double>(), uniform_loss(a).item<double>(),
                1e-5 * uniform_loss(a).item<double>());
}

TEST(UniformLoss, GradientsOfBothOrdersMatchFiniteDifferences) {
    at::Tensor x = test::sheet(1, 300, 9, at::kDouble).mul_(0.7).requires_grad_(true);
    at::Generator gen = at::detail::createCPUGenerator(10);
    at::Tensor v = at::randn(x.sizes(), gen, at::kDouble);
    at::Tensor grad = torch::autograd::grad({uniform_loss(x)}, {x}, {}, true, true)[0];
    at::Tensor hv = torch::autograd::grad({(grad * v).sum()}, {x})[0];
    auto value = [&](double t) { return uniform_loss((x + t * v).detach()).item<double>(); };
    auto slope = [&](double t) {
        at::Tensor y = (x + t * v).detach().requires_grad_(true);
        return (torch::autograd::grad({uniform_loss(y)}, {y})[0] * v).sum().item<double>();
    };
    const double h = 1e-7;
    const double numeric = (value(h) - value(-h)) / (2 * h);
    EXPECT_NEAR((grad * v).sum().item<double>(), numeric, 1e-5 * std::abs(numeric));
    const double numeric_second = (slope(h) - slope(-h)) / (2 * h);
    EXPECT_NEAR((hv * v).sum().item<double>(), numeric_second, 1e-4 * std::abs(numeric_second));
}

TEST(UniformLoss, CloudsTooSmallForAnyDiskGiveZero) {
    at::Tensor x = test::sheet(1, 64, 1).requires_grad_(true);  // ⌊64 · 0.012⌋ = 0
    at::Tensor loss = uniform_loss(x);
    EXPECT_EQ(loss.item<double>(), 0.0);
    EXPECT_TRUE(loss.requires_grad());
}

TEST(UniformLoss, RejectsBadInput) {
    EXPECT_TRUE(test::throws_input_error(
        [] {
            uniform_loss(at::zeros({1, 1, 3}));
        },
        {"uniform_loss", "at least 2 points"}));
    EXPECT_TRUE(test::throws_input_error(
        [] {
            uniform_loss(at::zeros({4, 3}));
        },
        {"uniform_loss"}));
    UniformLossOptions bad;
    bad.percentages = {1.5};
    EXPECT_TRUE(test::throws_input_error(
        [&] {
            uniform_loss(at::zeros({1, 8, 3}), bad);
        },
        {"(0, 1]"}));
    bad = {};
    bad.seed_fraction = 0;
    EXPECT_TRUE(test::throws_input_error(
        [&] {
            uniform_loss(at::zeros({1, 8, 3}), bad);
        },
        {"seed_fraction"}));
}

}  // namespace
}  // namespace pumeta
