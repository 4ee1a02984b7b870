// EMD loss: both matchings against an exact assignment (Hungarian algorithm, below) on small
// clouds, the plan's marginals, gradients (first and second order) against finite
// differences, invariances and input errors.
#include "pumeta/nn/emd_loss.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <cmath>
#include <limits>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

/// The minimum-cost perfect matching of an n×n cost matrix (Hungarian algorithm with
/// potentials, O(n³)): assignment[i] = column of row i.
std::vector<int64_t> hungarian(const std::vector<std::vector<double>>& cost) {
    const int64_t n = int64_t(cost.size());
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> u(n + 1, 0), v(n + 1, 0);
    std::vector<int64_t> row_of(n + 1, 0), way(n + 1, 0);  // 1-based; 0 is a virtual column
    for (int64_t i = 1; i <= n; ++i) {
        row_of[0] = i;
        int64_t j0 = 0;
        std::vector<double> min_to(n + 1, inf);
        std::vector<bool> used(n + 1, false);
        do {
            used[j0] = true;
            const int64_t i0 = row_of[j0];
            double delta = inf;
            int64_t j1 = 0;
            for (int64_t j = 1; j <= n; ++j) {
                if (used[j]) continue;
                const double reduced = cost[i0 - 1][j - 1] - u[i0] - v[j];
                if (reduced < min_to[j]) {
                    min_to[j] = reduced;
                    way[j] = j0;
                }
                if (min_to[j] < delta) {
                    delta = min_to[j];
                    j1 = j;
                }
            }
            for (int64_t j = 0; j <= n; ++j) {
                if (used[j]) {
                    u[row_of[j]] += delta;
                    v[j] -= delta;
                } else {
                    min_to[j] -= delta;
                }
            }
            j0 = j1;
        } while (row_of[j0] != 0);
        do {
            const int64_t j1 = way[j0];
            row_of[j0] = row_of[j1];
            j0 = j1;
        } while (j0 != 0);
    }
    std::vector<int64_t> assignment(n);
    for (int64_t j = 1; j <= n; ++j) assignment[row_of[j] - 1] = j - 1;
    return assignment;
}

std::vector<std::vector<double>> distance_matrix(const at::Tensor& a, const at::Tensor& b) {
    at::Tensor d = at::cdist(a.to(at::kDouble), b.to(at::kDouble));
    std::vector<std::vector<double>> cost(a.size(0), std::vector<double>(b.size(0)));
    for (int64_t i = 0; i < a.size(0); ++i)
        for (int64_t j = 0; j < b.size(0); ++j) cost[i][j] = d[i][j].item<double>();
    return cost;
}

/// Exact EMD of one pair [n,3]: the mean matched distance.
double exact_emd(const at::Tensor& a, const at::Tensor& b) {
    auto cost = distance_matrix(a, b);
    std::vector<int64_t> match = hungarian(cost);
    double total = 0;
    for (size_t i = 0; i < match.size(); ++i) total += cost[i][match[i]];
    return total / double(match.size());
}

/// Brute force over all permutations: the oracle of the oracle.
double permutation_emd(const at::Tensor& a, const at::Tensor& b) {
    auto cost = distance_matrix(a, b);
    std::vector<int64_t> perm(cost.size());
    for (size_t i = 0; i < perm.size(); ++i) perm[i] = int64_t(i);
    double best = std::numeric_limits<double>::infinity();
    do {
        double total = 0;
        for (size_t i = 0; i < perm.size(); ++i) total += cost[i][perm[i]];
        best = std::min(best, total);
    } while (std::next_permutation(perm.begin(), perm.end()));
    return best / double(perm.size());
}

/// Two clouds of a patch-like scale: a curved sheet and a jittered copy of another sampling.
std::pair<at::Tensor, at::Tensor> pair_of_clouds(int64_t n, uint64_t seed) {
    at::Tensor a = test::sheet(1, n, seed, at::kDouble)[0];
    at::Tensor b = test::sheet(1, n, seed + 1000, at::kDouble)[0];
    return {a, b};
}

TEST(Hungarian, MatchesBruteForceOverAllPermutations) {
    for (uint64_t seed = 1; seed <= 5; ++seed) {
        auto [a, b] = pair_of_clouds(7, seed);
        EXPECT_NEAR(exact_emd(a, b), permutation_emd(a, b), 1e-12) << seed;
    }
}

TEST(EmdLoss, AuctionIsWithinEpsilonOfTheExactEmd) {
    EmdOptions options;  // auction, epsilon 1e-4
    for (int64_t n : {16, 64, 128}) {
        for (uint64_t seed = 1; seed <= 3; ++seed) {
            auto [a, b] = pair_of_clouds(n, seed);
            const double exact = exact_emd(a, b);
            const double auction = emd_loss(a.unsqueeze(0), b.unsqueeze(0), options).item<double>();
            EXPECT_GE(auction, exact - 1e-9) << n << " points, seed " << seed;
            EXPECT_LE(auction, exact + options.epsilon + 1e-9) << n << " points, seed " << seed;
        }
    }
}

TEST(EmdLoss, ApproximateMatchingOverestimatesTheExactEmd) {
    EmdOptions options;
    options.matching = EmdMatching::kApproximate;
    for (int64_t n : {64, 256, 512}) {
        double worst = 0, sum = 0;
        for (uint64_t seed = 1; seed <= 2; ++seed) {
            // Patch-like: the sheet scaled into the unit ball.
            auto [a, b] = pair_of_clouds(n, seed);
            a = a / std::sqrt(2.0), b = b / std::sqrt(2.0);
            const double exact = exact_emd(a, b);
            const double approx = emd_loss(a.unsqueeze(0), b.unsqueeze(0), options).item<double>();
            const double relative = (approx - exact) / exact;
            EXPECT_GT(relative, -1e-6) << n << " points: below the optimum";
            worst = std::max(worst, relative);
            sum += relative;
        }
        // The figures of docs/design.md ("PU-GAN").
        std::printf("approximate EMD, %ld points: mean relative excess %.4f, worst %.4f\n", long(n),
                    sum / 2, worst);
        EXPECT_LT(worst, 0.5) << n << " points";
    }
}

TEST(EmdLoss, AuctionPlanIsAPermutationAndTheApproximateOneAtMostUnitMass) {
    auto [a, b] = pair_of_clouds(32, 7);
    at::Tensor plan = emd_plan(a.unsqueeze(0), b.unsqueeze(0));
    EXPECT_TRUE(at::allclose(plan.sum(2), at::ones({1, 32}, at::kDouble)));
    EXPECT_TRUE(at::allclose(plan.sum(1), at::ones({1, 32}, at::kDouble)));
    EXPECT_TRUE(((plan == 0) | (plan == 1)).all().item<bool>());

    EmdOptions approx;
    approx.matching = EmdMatching::kApproximate;
    plan = emd_plan(a.unsqueeze(0), b.unsqueeze(0), approx);
    EXPECT_LE(plan.sum(2).max().item<double>(), 1 + 1e-9);
    EXPECT_LE(plan.sum(1).max().item<double>(), 1 + 1e-9);
    EXPECT_GT(plan.sum().item<double>(), 0.95 * 32);
    EXPECT_GE(plan.min().item<double>(), 0.0);
}

TEST(EmdLoss, IdenticalCloudsCostNothingAndPermutationsDoNotMatter) {
    auto [a, b] = pair_of_clouds(40, 3);
    at::Tensor x = a.unsqueeze(0);
    at::Tensor shuffled = x.index_select(1, at::randperm(40, at::kLong));
    for (EmdMatching matching : {EmdMatching::kAuction, EmdMatching::kApproximate}) {
        EmdOptions options;
        options.matching = matching;
        EXPECT_LT(emd_loss(x, shuffled, options).item<double>(), 1e-5);
        at::Tensor y = b.unsqueeze(0);
        const double forward = emd_loss(x, y, options).item<double>();
        EXPECT_NEAR(emd_loss(shuffled, y, options).item<double>(), forward, 1e-4 * forward);
    }
    // A translation by t moves every matched point by |t|, at most.
    at::Tensor moved = x + at::tensor({0.3, 0.0, 0.0}, at::kDouble);
    EXPECT_NEAR(emd_loss(x, moved).item<double>(), 0.3, 1e-6);
}

TEST(EmdLoss, BatchElementsAreIndependentAndTheLossIsTheirMean) {
    auto [a0, b0] = pair_of_clouds(24, 11);
    auto [a1, b1] = pair_of_clouds(24, 12);
    const double first = emd_loss(a0.unsqueeze(0), b0.unsqueeze(0)).item<double>();
    const double second = emd_loss(a1.unsqueeze(0), b1.unsqueeze(0)).item<double>();
    const double both = emd_loss(at::stack({a0, a1}), at::stack({b0, b1})).item<double>();
    EXPECT_NEAR(both, 0.5 * (first + second), 1e-12);
}

TEST(EmdLoss, GradientsOfBothOrdersMatchFiniteDifferencesForTheAuction) {
    auto [a, b] = pair_of_clouds(20, 21);
    at::Tensor x = a.unsqueeze(0).requires_grad_(true);
    at::Tensor y = b.unsqueeze(0);
    at::Tensor direction = at::randn(x.sizes(), at::kDouble);
    at::Tensor loss = emd_loss(x, y);
    at::Tensor grad = torch::autograd::grad({loss}, {x}, {}, true, true)[0];
    const double analytic = (grad * direction).sum().item<double>();
    // Second order: d/dt of ⟨∇L(x + t v), v⟩.
    at::Tensor hv = torch::autograd::grad({(grad * direction).sum()}, {x})[0];
    const double second = (hv * direction).sum().item<double>();
    // The assignment is locally constant: small steps leave it alone.
    const double h = 1e-6;
    auto value = [&](double t) { return emd_loss((x + t * direction).detach(), y).item<double>(); };
    const double numeric = (value(h) - value(-h)) / (2 * h);
    const double numeric_second = (value(h) - 2 * value(0) + value(-h)) / (h * h);
    EXPECT_NEAR(analytic, numeric, 1e-6 * std::abs(numeric) + 1e-9);
    EXPECT_NEAR(second, numeric_second, 1e-3 * std::abs(second) + 1e-3);
    EXPECT_GT(std::abs(second), 1e-3);  // a curved loss, so the second check has teeth
}

TEST(EmdLoss, FloatInputsWork) {
    at::Tensor a = test::sheet(2, 32, 5), b = test::sheet(2, 32, 6);
    at::Tensor loss = emd_loss(a, b);
    EXPECT_EQ(loss.scalar_type(), at::kFloat);
    EXPECT_NEAR(loss.item<double>(), emd_loss(a.to(at::kDouble), b.to(at::kDouble)).item<double>(),
                1e-5);
}

TEST(EmdLoss, RejectsCloudsOfDifferentSizes) {
    at::Tensor a = test::sheet(1, 8, 1), b = test::sheet(1, 9, 2);
    EXPECT_TRUE(test::throws_input_error([&] { emd_loss(a, b); }, {"emd_loss", "equal shape"}));
    EmdOptions bad;
    bad.epsilon = 0;
    EXPECT_TRUE(test::throws_input_error([&] { emd_loss(a, a, bad); }, {"epsilon"}));
}

}  // namespace
}  // namespace pumeta
