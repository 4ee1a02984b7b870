// Repulsion loss against a brute-force oracle (all pairwise distances, sorted) and a hand
// computed pair.
#include "pumeta/nn/repulsion_loss.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <cmath>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

// Mean over points of the hinge on their `neighbors` nearest others, from the full distance
// matrix (the point itself excluded by an infinite diagonal).
at::Tensor brute_force(const at::Tensor& points, int64_t neighbors, double h) {
    at::Tensor diff = points.unsqueeze(2) - points.unsqueeze(1);  // [B,N,N,3]
    at::Tensor sq = diff.pow(2).sum(-1);
    at::Tensor masked =
        sq.detach() + at::eye(points.size(1), points.options()).mul(1e30).unsqueeze(0);
    at::Tensor order = masked.argsort(/*dim=*/int64_t{-1}).narrow(-1, 0, neighbors);
    return at::relu(h - sq.gather(-1, order)).mean();
}

}  // namespace

TEST(RepulsionLoss, HandComputedPair) {
    // Two points 0.01 apart: each sees the other at squared distance 1e-4 < h.
    at::Tensor close = at::tensor({0.f, 0.f, 0.f, 0.01f, 0.f, 0.f}).view({1, 2, 3});
    EXPECT_NEAR(repulsion_loss(close, 1).item<double>(), 1e-3 - 1e-4, 1e-9);
    at::Tensor far = at::tensor({0.f, 0.f, 0.f, 0.5f, 0.f, 0.f}).view({1, 2, 3});
    EXPECT_EQ(repulsion_loss(far, 1).item<double>(), 0.0);
}

TEST(RepulsionLoss, MatchesBruteForceInValueAndGradient) {
    // Crowded points (spacing ~0.01) so that most hinges are active, in double precision.
    at::Generator gen = at::detail::createCPUGenerator(3);
    at::Tensor points = (at::rand({2, 60, 3}, gen, at::TensorOptions().dtype(at::kDouble)) * 0.08)
                            .requires_grad_(true);
    for (int64_t neighbors : {1, 4, 7}) {
        at::Tensor ours = repulsion_loss(points, neighbors);
        at::Tensor expected = brute_force(points, neighbors, 1e-3);
        EXPECT_GT(expected.item<double>(), 1e-5);
        EXPECT_NEAR(ours.item<double>(), expected.item<double>(), 1e-12);
        at::Tensor g_ours = torch::autograd::grad({ours}, {points})[0];
        at::Tensor g_expected = torch::autograd::grad({expected}, {points})[0];
        EXPECT_TRUE(at::allclose(g_ours, g_expected, 1e-9, 1e-12)) << neighbors;
    }
}

TEST(RepulsionLoss, TooFewPointsAreInputErrors) {
    EXPECT_THROW(repulsion_loss(at::zeros({1, 4, 3}), 4), InputError);
    EXPECT_THROW(repulsion_loss(at::zeros({1, 4, 3}), 0), InputError);
    EXPECT_THROW(repulsion_loss(at::zeros({4, 3}), 1), InputError);
}

TEST(PuNetRepulsionLoss, HandComputedPairAndItsGradient) {
    // Two points 0.01 apart, one neighbour each: 0.07 − d·exp(−d²/0.03²) with d = 0.01; the
    // gradient pushes them apart (d·e^{−d²/h²} grows with d below h/√2).
    at::Tensor close = at::tensor({0.0, 0.0, 0.0, 0.01, 0.0, 0.0}, at::kDouble).view({1, 2, 3});
    close.requires_grad_(true);
    at::Tensor loss = punet_repulsion_loss(close, 1);
    EXPECT_NEAR(loss.item<double>(), 0.07 - 0.01 * std::exp(-1e-4 / 9e-4), 1e-12);
    loss.backward();
    EXPECT_GT(close.grad()[0][0][0].item<double>(), 0);
    EXPECT_LT(close.grad()[0][1][0].item<double>(), 0);
    EXPECT_THROW(punet_repulsion_loss(at::zeros({1, 4, 3}), 4), InputError);
}

}  // namespace pumeta
