#include "pumeta/nn/init.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>

#include "pumeta/core/error.h"

namespace pumeta {

TEST(Init, SameSeedSameWeightsOtherSeedOtherWeights) {
    auto make = [](uint64_t seed) {
        ParamMap p;
        std::mt19937_64 rng(seed);
        add_linear(p, "a", 16, 8, true, rng);
        add_linear(p, "b", 8, 4, false, rng);
        return p;
    };
    ParamMap first = make(7), again = make(7), other = make(8);
    ASSERT_EQ(first.size(), 3u);
    for (const auto& [name, tensor] : first) {
        EXPECT_TRUE(tensor.requires_grad()) << name;
        EXPECT_TRUE(tensor.is_leaf()) << name;
        EXPECT_TRUE(tensor.equal(again.at(name))) << name;
    }
    EXPECT_FALSE(first.at("a.weight").equal(other.at("a.weight")));
    EXPECT_TRUE(first.at("a.bias").equal(at::zeros({8})));
}

TEST(Init, XavierUniformHasTheGlorotRangeAndVariance) {
    ParamMap p;
    std::mt19937_64 rng(3);
    add_xavier_uniform(p, "w", 200, 100, rng);
    at::Tensor w = p.at("w").detach().to(at::kDouble);
    const double limit = std::sqrt(6.0 / 300.0);
    EXPECT_LE(w.abs().max().item<double>(), limit);
    EXPECT_GT(w.abs().max().item<double>(), 0.99 * limit);
    EXPECT_NEAR(w.mean().item<double>(), 0.0, 0.01 * limit);
    // Uniform(-a, a) has variance a²/3 = 2 / (fan_in + fan_out).
    EXPECT_NEAR(w.var().item<double>(), limit * limit / 3, 0.02 * limit * limit / 3);
}

TEST(Init, AddingANameTwiceIsABug) {
    ParamMap p;
    std::mt19937_64 rng(0);
    add_zeros(p, "x", 3);
    EXPECT_THROW(add_zeros(p, "x", 3), InternalError);
}

TEST(Init, Uniform01IsUniformOnTheUnitInterval) {
    std::mt19937_64 rng(1);
    double sum = 0, sum_sq = 0;
    const int n = 100000;
    for (int i = 0; i < n; ++i) {
        double u = uniform01(rng);
        ASSERT_GE(u, 0.0);
        ASSERT_LT(u, 1.0);
        sum += u;
        sum_sq += u * u;
    }
    EXPECT_NEAR(sum / n, 0.5, 0.005);
    EXPECT_NEAR(sum_sq / n, 1.0 / 3.0, 0.005);
}

}  // namespace pumeta
