#include "pumeta/nn/graph.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <algorithm>
#include <numeric>
#include <vector>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

at::Tensor random_features(int64_t b, int64_t n, int64_t c, uint64_t seed,
                           at::ScalarType type = at::kDouble) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    return at::randn({b, n, c}, gen, at::TensorOptions().dtype(type));
}

}  // namespace

TEST(KnnGraph, MatchesSortedBruteForceAndExcludesSelf) {
    // k = 39 of 40 candidates exercises the selection's fallback path, small k the fast one.
    const int64_t b = 2, n = 41, c = 7;
    for (at::ScalarType type : {at::kDouble, at::kFloat}) {
        at::Tensor x = random_features(b, n, c, 1).to(type);
        at::Tensor exact = x.to(at::kDouble);
        auto acc = exact.accessor<double, 3>();
        for (int64_t k : {1, 9, 25, 40}) {
            SCOPED_TRACE("k = " + std::to_string(k));
            at::Tensor idx = knn_graph(x, k);
            ASSERT_EQ(idx.sizes(), (std::vector<int64_t>{b, n, k}));
            for (int64_t e = 0; e < b; ++e) {
                for (int64_t i = 0; i < n; ++i) {
                    std::vector<std::pair<double, int64_t>> all;
                    for (int64_t j = 0; j < n; ++j) {
                        if (j == i) continue;
                        double d = 0;
                        for (int64_t ch = 0; ch < c; ++ch)
                            d += std::pow(acc[e][i][ch] - acc[e][j][ch], 2);
                        all.push_back({d, j});
                    }
                    std::vector<double> distance(n, -1);
                    for (const auto& [d, j] : all) distance[j] = d;
                    std::sort(all.begin(), all.end());
                    // Ranked by float32 scores from a BLAS product: a neighbour whose exact
                    // distance ties the oracle's within float rounding may take its rank.
                    for (int64_t j = 0; j < k; ++j) {
                        const int64_t got = idx[e][i][j].item<int64_t>();
                        ASSERT_GE(distance[got], 0) << e << " " << i;  // never itself
                        ASSERT_NEAR(distance[got], all[j].first, 1e-5 * (1 + all[j].first))
                            << e << " " << i << " rank " << j;
                    }
                }
            }
        }
    }
}

TEST(KnnGraph, DuplicatePointsAreNeighboursButNeverTheirOwn) {
    at::Tensor x = random_features(1, 10, 3, 2, at::kFloat);
    x[0][1] = x[0][0];  // point 1 duplicates point 0
    at::Tensor idx = knn_graph(x, 4);
    EXPECT_EQ(idx[0][0][0].item<int64_t>(), 1);
    EXPECT_EQ(idx[0][1][0].item<int64_t>(), 0);
    at::Tensor self = at::arange(10, at::kLong).view({1, 10, 1});
    EXPECT_FALSE(idx.eq(self).any().item<bool>());
}

TEST(KnnGraph, RejectsKOutsideRange) {
    at::Tensor x = random_features(1, 5, 2, 3, at::kFloat);
    EXPECT_THROW(knn_graph(x, 5), InputError);
    EXPECT_THROW(knn_graph(x, 0), InputError);
    EXPECT_NO_THROW(knn_graph(x, 4));
}

TEST(GatherNeighbors, PicksRowsOfTheSameBatchElement) {
    at::Tensor x = random_features(3, 6, 4, 4);
    at::Generator gen = at::detail::createCPUGenerator(5);
    at::Tensor idx = at::randint(6, {3, 6, 5}, gen, at::TensorOptions().dtype(at::kLong));
    at::Tensor out = gather_neighbors(x, idx);
    ASSERT_EQ(out.sizes(), (std::vector<int64_t>{3, 6, 5, 4}));
    for (int64_t b = 0; b < 3; ++b)
        for (int64_t i = 0; i < 6; ++i)
            for (int64_t j = 0; j < 5; ++j)
                EXPECT_TRUE(out[b][i][j].equal(x[b][idx[b][i][j].item<int64_t>()]));
}

TEST(GatherMax, EqualsMaxOfGatheredNeighboursWithSameFirstAndSecondOrderGradients) {
    at::Tensor x = random_features(2, 12, 5, 6).requires_grad_(true);
    at::Tensor idx = knn_graph(x, 4);
    at::Tensor weight = random_features(2, 12, 5, 7);
    auto objective = [&](bool fast) {
        at::Tensor m = fast ? gather_max(x, idx) : gather_neighbors(x, idx).amax(2);
        return (m.pow(3) * weight).sum();  // nonlinear, so the second derivative is not zero
    };
    at::Tensor fast_value = objective(true), slow_value = objective(false);
    EXPECT_NEAR(fast_value.item<double>(), slow_value.item<double>(), 1e-12);
    at::Tensor fast_grad = torch::autograd::grad({fast_value}, {x}, {}, true, true)[0];
    at::Tensor slow_grad = torch::autograd::grad({slow_value}, {x}, {}, true, true)[0];
    EXPECT_TRUE(at::allclose(fast_grad, slow_grad, 0, 1e-12));
    EXPECT_GT(fast_grad.abs().sum().item<double>(), 0);
    at::Tensor fast_second = torch::autograd::grad({fast_grad.pow(2).sum()}, {x})[0];
    at::Tensor slow_second = torch::autograd::grad({slow_grad.pow(2).sum()}, {x})[0];
    EXPECT_TRUE(at::allclose(fast_second, slow_second, 0, 1e-12));
    EXPECT_GT(fast_second.abs().sum().item<double>(), 0);
}

TEST(MaxOverNeighbors, EqualsAmaxWithSameFirstAndSecondOrderGradients) {
    at::Generator gen = at::detail::createCPUGenerator(9);
    at::Tensor y =
        at::randn({2, 5, 6, 7}, gen, at::TensorOptions().dtype(at::kDouble)).requires_grad_(true);
    at::Tensor weight = at::randn({2, 5, 7}, gen, at::TensorOptions().dtype(at::kDouble));
    at::Tensor fast = (max_over_neighbors(y).pow(3) * weight).sum();
    at::Tensor slow = (y.amax(2).pow(3) * weight).sum();
    EXPECT_NEAR(fast.item<double>(), slow.item<double>(), 1e-12);
    at::Tensor fast_grad = torch::autograd::grad({fast}, {y}, {}, true, true)[0];
    at::Tensor slow_grad = torch::autograd::grad({slow}, {y}, {}, true, true)[0];
    EXPECT_TRUE(at::allclose(fast_grad, slow_grad, 0, 1e-12));
    at::Tensor fast_second = torch::autograd::grad({fast_grad.pow(2).sum()}, {y})[0];
    at::Tensor slow_second = torch::autograd::grad({slow_grad.pow(2).sum()}, {y})[0];
    EXPECT_TRUE(at::allclose(fast_second, slow_second, 0, 1e-12));
    EXPECT_GT(fast_second.abs().sum().item<double>(), 0);
    // A strided (non-contiguous) input gives the same maxima.
    at::Tensor strided = y.detach().transpose(1, 2).contiguous().transpose(1, 2);
    EXPECT_TRUE(max_over_neighbors(strided).equal(y.detach().amax(2)));
}

TEST(GatherMax, FloatAndDoubleAgreeAndBadIndicesAreRejected) {
    at::Tensor x = random_features(2, 30, 16, 8);
    at::Tensor idx = knn_graph(x, 6);
    EXPECT_TRUE(at::allclose(gather_max(x.to(at::kFloat), idx).to(at::kDouble), gather_max(x, idx),
                             0, 1e-6));
    at::Tensor bad = idx.clone();
    bad[1][3][2] = 30;
    EXPECT_THROW(gather_max(x, bad), InputError);
    EXPECT_THROW(gather_max(x, idx.narrow(1, 0, 29)), InputError);
}

}  // namespace pumeta
