// Batch norm over active sites, pooling, pruning, concatenation and addition onto a superset,
// against torch's batch norm and brute-force oracles.
#include "pumeta/nn/sparse/sparse_ops.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <map>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/nn/batch_norm.h"
#include "pumeta/nn/sparse/sparse_batch_norm.h"

namespace pumeta {
namespace {

CoordinateSetPtr sites(std::vector<std::array<int32_t, 4>> rows, int64_t stride = 1) {
    at::Tensor t = at::empty({int64_t(rows.size()), 4}, at::kInt);
    for (size_t i = 0; i < rows.size(); ++i)
        for (int a = 0; a < 4; ++a) t[i][a] = rows[i][a];
    return CoordinateSet::create(t, stride);
}

CoordinateSetPtr line(int64_t batches, int64_t length) {
    std::vector<std::array<int32_t, 4>> rows;
    for (int32_t b = 0; b < batches; ++b)
        for (int32_t x = 0; x < length; ++x) rows.push_back({b, x, b, 0});
    return sites(rows);
}

TEST(SparseBatchNorm, MatchesTorchBatchNormInTrainingAndEvaluation) {
    ParamMap params, buffers;
    add_batch_norm(params, buffers, "bn", 3);
    at::manual_seed(1);
    params["bn.gamma"] = at::rand({3}).add(0.5).requires_grad_(true);
    params["bn.beta"] = at::randn({3}).requires_grad_(true);
    SparseTensor x(line(2, 25), at::randn({50, 3}) * 3 + 1);

    BatchNormContext train;
    train.update = &buffers;
    SparseTensor ours = sparse_batch_norm(x, params, "bn", train);
    EXPECT_EQ(ours.coords(), x.coords());
    at::Tensor running_mean = at::zeros({3}), running_var = at::ones({3});
    at::Tensor theirs =
        at::batch_norm(x.features(), params["bn.gamma"], params["bn.beta"], running_mean,
                       running_var, /*training=*/true, 0.1, 1e-5, false);
    EXPECT_TRUE(at::allclose(ours.features(), theirs, 1e-5, 1e-5));
    // Both moved their running statistics with momentum 0.1 and the unbiased variance.
    EXPECT_TRUE(at::allclose(buffers["bn.running_mean"], running_mean, 1e-5, 1e-6));
    EXPECT_TRUE(at::allclose(buffers["bn.running_var"], running_var, 1e-5, 1e-6));

    BatchNormContext eval;
    eval.batch_statistics = false;
    eval.running = &buffers;
    at::Tensor ours_eval = sparse_batch_norm(x, params, "bn", eval).features();
    at::Tensor theirs_eval = at::batch_norm(x.features(), params["bn.gamma"], params["bn.beta"],
                                            running_mean, running_var, false, 0.1, 1e-5, false);
    EXPECT_TRUE(at::allclose(ours_eval, theirs_eval, 1e-5, 1e-5));
}

TEST(SparseBatchNorm, SecondDerivativeMatchesFiniteDifferences) {
    at::manual_seed(2);
    auto set = line(1, 20);
    at::Tensor x0 = at::randn({20, 2}, at::kDouble);
    at::Tensor w0 = at::rand({2}, at::kDouble) + 0.5, b0 = at::randn({2}, at::kDouble);
    at::Tensor r = at::randn({20, 2}, at::kDouble);
    at::Tensor ux = at::randn_like(x0), uw = at::randn_like(w0);
    at::Tensor vx = at::randn_like(x0), vw = at::randn_like(w0);
    // s = <∇_{x,γ} Σ tanh(BN(x)) r, u>, and its derivative along v.
    auto directional = [&](const at::Tensor& xs, const at::Tensor& ws, bool graph) {
        at::Tensor x = xs.detach().requires_grad_(true), w = ws.detach().requires_grad_(true);
        ParamMap p{{"bn.gamma", w}, {"bn.beta", b0}};
        at::Tensor y = sparse_batch_norm(SparseTensor(set, x), p, "bn", {}).features();
        auto g = torch::autograd::grad({(at::tanh(y) * r).sum()}, {x, w}, {}, graph, graph);
        return std::tuple{(g[0] * ux).sum() + (g[1] * uw).sum(), x, w};
    };
    auto [s, x, w] = directional(x0, w0, true);
    auto h = torch::autograd::grad({s}, {x, w});
    double analytic = ((h[0] * vx).sum() + (h[1] * vw).sum()).item<double>();
    const double eps = 1e-5;
    double numeric =
        (std::get<0>(directional(x0 + eps * vx, w0 + eps * vw, false)).item<double>() -
         std::get<0>(directional(x0 - eps * vx, w0 - eps * vw, false)).item<double>()) /
        (2 * eps);
    EXPECT_GT(std::abs(numeric), 1e-6);
    EXPECT_NEAR(analytic, numeric, 1e-6 * std::max(1.0, std::abs(numeric)));
}

TEST(SparseBatchNorm, OneSiteNormalisesToBetaAndLeavesRunningStatistics) {
    ParamMap params, buffers;
    add_batch_norm(params, buffers, "bn", 2);
    ParamMap before = buffers;
    BatchNormContext context;
    context.update = &buffers;
    SparseTensor one(line(1, 1), at::tensor({3.0f, -1.0f}).view({1, 2}));
    EXPECT_TRUE(
        at::allclose(sparse_batch_norm(one, params, "bn", context).features(), at::zeros({1, 2})));
    for (auto& [name, b] : buffers) EXPECT_TRUE(b.equal(before[name])) << name;
}

TEST(SparseOps, GlobalAveragePoolAndBroadcastArePerBatchElement) {
    auto set = sites({{0, 0, 0, 0}, {1, 5, 5, 5}, {0, 1, 0, 0}, {2, 0, 0, 0}, {0, 2, 0, 0}});
    at::Tensor f = at::tensor({1.f, 10.f, 2.f, 20.f, 3.f, 30.f, 4.f, 40.f, 5.f, 50.f}).view({5, 2});
    at::Tensor pooled = global_average_pool(SparseTensor(set, f));
    at::Tensor expected = at::tensor({3.f, 30.f, 2.f, 20.f, 4.f, 40.f}).view({3, 2});
    EXPECT_TRUE(at::allclose(pooled, expected));
    SparseTensor spread = broadcast_to_sites(pooled, set);
    EXPECT_TRUE(at::allclose(spread.features(),
                             expected.index_select(0, at::tensor({0, 1, 0, 2, 0}, at::kLong))));
}

TEST(SparseOps, PruneKeepsMaskedSitesInOrder) {
    auto set = line(2, 4);
    at::Tensor f = at::arange(8, at::kFloat).view({8, 1});
    at::Tensor keep = at::tensor({1, 0, 0, 1, 1, 1, 0, 0}).to(at::kBool);
    SparseTensor kept = prune(SparseTensor(set, f), keep);
    ASSERT_EQ(kept.size(), 4);
    EXPECT_TRUE(kept.features().view(-1).equal(at::tensor({0.f, 3.f, 4.f, 5.f})));
    EXPECT_TRUE(kept.coords()->coords().equal(
        set->coords().index_select(0, at::tensor({0, 3, 4, 5}, at::kLong))));
    EXPECT_THROW(prune(SparseTensor(set, f), at::ones({3}, at::kBool)), InputError);
}

TEST(SparseOps, AddOntoASupersetAddsAtTheSharedSites) {
    auto big = line(1, 6);
    auto small = sites({{0, 4, 0, 0}, {0, 1, 0, 0}});
    at::Tensor a = at::ones({6, 2});
    at::Tensor b = at::tensor({10.f, 20.f, 30.f, 40.f}).view({2, 2});
    SparseTensor sum = add_onto(SparseTensor(big, a), SparseTensor(small, b));
    EXPECT_EQ(sum.coords(), big);
    at::Tensor expected = at::ones({6, 2});
    expected[4] += b[0];
    expected[1] += b[1];
    EXPECT_TRUE(at::allclose(sum.features(), expected));
    // Not a subset: an error, not a silent drop.
    EXPECT_THROW(add_onto(SparseTensor(small, b), SparseTensor(big, a)), InputError);
}

TEST(SparseOps, CatNeedsTheSameCoordinateSet) {
    auto set = line(1, 3);
    SparseTensor a(set, at::ones({3, 1})), b(set, at::zeros({3, 2}));
    EXPECT_EQ(sparse_cat(a, b).channels(), 3);
    EXPECT_THROW(sparse_cat(a, SparseTensor(line(1, 3), at::zeros({3, 2}))), InputError);
}

}  // namespace
}  // namespace pumeta
