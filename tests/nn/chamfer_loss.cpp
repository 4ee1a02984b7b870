#include "pumeta/nn/chamfer_loss.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

at::Tensor random_cloud(int64_t b, int64_t n, uint64_t seed, at::ScalarType type = at::kDouble) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    return at::rand({b, n, 3}, gen, at::TensorOptions().dtype(type));
}

// All pairwise squared distances from coordinate differences, min over each side.
at::Tensor brute_force_chamfer(const at::Tensor& pred, const at::Tensor& target) {
    at::Tensor d = (pred.unsqueeze(2) - target.unsqueeze(1)).pow(2).sum(-1);  // [B,N,M]
    return 0.5 * std::get<0>(d.min(2)).mean(1) + 0.5 * std::get<0>(d.min(1)).mean(1);
}

}  // namespace

TEST(ChamferLoss, HandComputedValue) {
    // pred {0, 2} and target {0, 1, 3} on a line: forward (0, 1) -> 1/2, backward (0, 1, 1)
    // -> 2/3; loss = 0.5·0.5 + 0.5·2/3 = 7/12.
    at::Tensor pred = at::tensor({0., 0., 0., 2., 0., 0.}, at::kDouble).view({1, 2, 3});
    at::Tensor target =
        at::tensor({0., 0., 0., 1., 0., 0., 3., 0., 0.}, at::kDouble).view({1, 3, 3});
    EXPECT_NEAR(chamfer_loss(pred, target).item<double>(), 7.0 / 12.0, 1e-15);
}

TEST(ChamferLoss, EqualsBruteForceMeanOverBatchForFloatAndDouble) {
    at::Tensor pred = random_cloud(3, 50, 1), target = random_cloud(3, 70, 2);
    double expected = brute_force_chamfer(pred, target).mean().item<double>();
    EXPECT_NEAR(chamfer_loss(pred, target).item<double>(), expected, 1e-14);
    EXPECT_NEAR(chamfer_loss(pred.to(at::kFloat), target.to(at::kFloat)).item<double>(), expected,
                1e-6);
    EXPECT_NEAR(chamfer_loss(pred, pred).item<double>(), 0.0, 0.0);
}

TEST(ChamferLoss, NearestIndicesMatchBruteForce) {
    at::Tensor q = random_cloud(2, 40, 3), p = random_cloud(2, 33, 4);
    at::Tensor d = (q.unsqueeze(2) - p.unsqueeze(1)).pow(2).sum(-1);
    EXPECT_TRUE(nearest_point_indices(q, p).equal(d.argmin(2)));
}

TEST(ChamferLoss, FirstAndSecondDerivativesMatchBruteForceMin) {
    at::Tensor pred = random_cloud(2, 30, 5).requires_grad_(true);
    at::Tensor target = random_cloud(2, 45, 6).requires_grad_(true);
    at::Tensor weights = at::tensor({0.3, 1.7}, at::kDouble);
    auto first = [&](bool fast) {
        at::Tensor value =
            fast ? chamfer_loss(pred, target) : brute_force_chamfer(pred, target).mean();
        return torch::autograd::grad({value}, {pred, target}, {}, true, true);
    };
    auto fast = first(true), slow = first(false);
    for (int i = 0; i < 2; ++i) EXPECT_TRUE(at::allclose(fast[i], slow[i], 0, 1e-14));
    // d/dθ of |∇L|² weighted: involves the Hessian, non-zero for squared distances.
    auto second = [&](const std::vector<at::Tensor>& g) {
        return torch::autograd::grad(
            {(g[0].pow(2) * weights.view({2, 1, 1})).sum() + g[1].pow(2).sum()}, {pred, target});
    };
    auto fast2 = second(fast), slow2 = second(slow);
    for (int i = 0; i < 2; ++i) {
        EXPECT_TRUE(at::allclose(fast2[i], slow2[i], 0, 1e-14));
        EXPECT_GT(fast2[i].abs().sum().item<double>(), 0);
    }
}

TEST(ChamferLoss, RejectsMismatchedBatches) {
    EXPECT_THROW(chamfer_loss(random_cloud(2, 5, 1), random_cloud(3, 5, 2)), InputError);
    EXPECT_THROW(chamfer_loss(at::zeros({2, 5, 2}), at::zeros({2, 5, 2})), InputError);
}

}  // namespace pumeta
