#include "pumeta/eval/paired_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "pumeta/core/error.h"

namespace pumeta {
namespace {

TEST(PairedStats, ConstantDifferenceHasAZeroWidthIntervalAtThatDifference) {
    std::vector<double> base = {1.0, 2.0, 3.0, 4.0}, method = {0.9, 1.9, 2.9, 3.9};
    PairedComparison c = compare_paired(base, method);
    EXPECT_EQ(c.count, 4);
    EXPECT_NEAR(c.mean_base, 2.5, 1e-12);
    EXPECT_NEAR(c.mean_difference, -0.1, 1e-12);
    EXPECT_NEAR(c.relative_change, -0.04, 1e-12);
    EXPECT_NEAR(c.ci_low, -0.1, 1e-12);
    EXPECT_NEAR(c.ci_high, -0.1, 1e-12);
    EXPECT_TRUE(c.excludes_zero());
    EXPECT_DOUBLE_EQ(c.fraction_improved, 1.0);
    // Higher is better (PSNR): the same numbers are all worse.
    EXPECT_DOUBLE_EQ(compare_paired(base, method, true).fraction_improved, 0.0);
}

TEST(PairedStats, NoiseAroundZeroGivesAnIntervalContainingZeroOfTheRightWidth) {
    std::mt19937_64 rng(5);
    std::normal_distribution<double> noise(0.0, 1.0);
    std::vector<double> base(400), method(400);
    for (size_t i = 0; i < base.size(); ++i) {
        base[i] = 10 + noise(rng);
        method[i] = base[i] + noise(rng);  // differences ~ N(0, 1)
    }
    PairedComparison c = compare_paired(base, method, false, 4000, 3);
    EXPECT_LT(c.ci_low, c.mean_difference);
    EXPECT_GT(c.ci_high, c.mean_difference);
    // Normal theory: the 95 % interval of a mean of 400 unit-variance values is ±1.96/20.
    double half_width = 0.5 * (c.ci_high - c.ci_low);
    EXPECT_NEAR(half_width, 1.96 / 20, 0.02);
    EXPECT_FALSE(c.excludes_zero()) << c.ci_low << " " << c.ci_high;
    // Deterministic for a seed.
    PairedComparison again = compare_paired(base, method, false, 4000, 3);
    EXPECT_EQ(c.ci_low, again.ci_low);
    EXPECT_EQ(c.ci_high, again.ci_high);
}

TEST(PairedStats, NonFinitePairsAreDroppedAndMismatchedLengthsRejected) {
    PairedComparison c = compare_paired({1.0, NAN, 3.0}, {2.0, 1.0, INFINITY});
    EXPECT_EQ(c.count, 1);
    EXPECT_DOUBLE_EQ(c.mean_difference, 1.0);
    EXPECT_THROW(compare_paired({1.0}, {1.0, 2.0}), InputError);
    EXPECT_EQ(compare_paired({}, {}).count, 0);
}

}  // namespace
}  // namespace pumeta
