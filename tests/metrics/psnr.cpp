// PSNR (pc_error D1) against hand-computed fixtures and an independent oracle.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "metrics/metric_oracles.h"
#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/metrics.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::cloud;

constexpr double kInf = std::numeric_limits<double>::infinity();

void expect_relative_near(double actual, double expected, double tolerance) {
    EXPECT_NEAR(actual, expected, tolerance * std::abs(expected)) << "expected " << expected;
}

// The pc_error procedure written out in the most direct way: double transform, duplicates
// merged with at::unique_dim, O(N*M) nearest neighbours.
double oracle_psnr(const at::Tensor& pred, const at::Tensor& gt) {
    at::Tensor g = gt.to(at::kDouble), p = pred.to(at::kDouble);
    at::Tensor lo = std::get<0>(g.min(0));
    double scale = 1023.0 / (std::get<0>(g.max(0)) - lo).max().item<double>();
    at::Tensor a = std::get<0>(at::unique_dim((p - lo) * scale, 0));
    at::Tensor b = std::get<0>(at::unique_dim((g - lo) * scale, 0));
    auto one_way = [](const at::Tensor& from, const at::Tensor& to) {
        double mse = test::mean(test::brute_force_sq_distances(from, to));
        return 10 * std::log10(3 * 1023.0 * 1023.0 / mse);
    };
    return std::min(one_way(a, b), one_way(b, a));
}

// gt = {(0,0,0), (2,0,0), (0,2,0), (0,0,2)}: bounding-box minimum 0, longest side 2, so
// both clouds are scaled by s = 1023/2. pred = {(0,0,0), (2,0,0), (1,1,0)}.
// Squared NN distances before scaling (see chamfer.cpp): pred -> gt 0, 0, 2 (MSE 2/3 s^2);
// gt -> pred 0, 0, 2, 4 (MSE 3/2 s^2). PSNR = 10 log10(3 * 1023^2 / MSE):
// pred -> gt: 10 log10(3 * 4 / (2/3)) = 10 log10(18); gt -> pred: 10 log10(3 * 4 / (3/2)) =
// 10 log10(8) = 9.0309 dB, the minimum.
TEST(Psnr, HandComputedFixture) {
    at::Tensor gt = cloud({0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 2});
    at::Tensor pred = cloud({0, 0, 0, 2, 0, 0, 1, 1, 0});
    expect_relative_near(psnr_d1(pred, gt), 10 * std::log10(8.0), 1e-6);
    // The result is the minimum over both directions, so it is symmetric.
    expect_relative_near(psnr_d1(gt, pred), 10 * std::log10(8.0), 1e-6);
}

// pred = the 4 gt points, plus (2,2,2), plus (0,0,0) three more times: 8 points, 5 distinct.
// gt -> pred: every gt point is in pred, MSE 0. pred -> gt: only (2,2,2) is off, at squared
// distance 8 from (2,0,0), (0,2,0) and (0,0,2). With pc_error's merging MSE = 8/5 s^2 and
// PSNR = 10 log10(3 * 4 / (8/5)) = 10 log10(7.5) = 8.7506 dB; counting the duplicates would
// give MSE = 8/8 s^2 and 10 log10(12) = 10.79 dB.
TEST(Psnr, DuplicatePointsAreMergedAsPcErrorDoes) {
    at::Tensor gt = cloud({0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 2});
    at::Tensor pred = cloud({0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 2,  //
                             2, 2, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0});
    expect_relative_near(psnr_d1(pred, gt), 10 * std::log10(7.5), 1e-6);

    // Duplicates in the GT are merged too: with (0,0,2) twice, gt -> pred of the first
    // fixture would become (0 + 0 + 2 + 4 + 4) / 5 = 2 s^2 unmerged; merged it stays 3/2 s^2.
    at::Tensor gt_duplicated = cloud({0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 2});
    at::Tensor pred_first = cloud({0, 0, 0, 2, 0, 0, 1, 1, 0});
    expect_relative_near(psnr_d1(pred_first, gt_duplicated), 10 * std::log10(8.0), 1e-6);
}

TEST(Psnr, IdenticalCloudsAreInfinite) {
    at::Tensor points = uniform_random_points(200, 5);
    EXPECT_EQ(psnr_d1(points, points), kInf);
    // Same set of points, different multiplicities: still identical after merging.
    EXPECT_EQ(psnr_d1(at::cat({points, points.slice(0, 0, 50)}), points), kInf);
}

TEST(Psnr, MatchesIndependentOracleOnRandomClouds) {
    for (uint64_t seed : {1, 2, 3}) {
        at::Tensor gt = uniform_random_points(300 + 100 * seed, seed);
        // Duplicates in both clouds, and a prediction reaching outside the GT's box.
        at::Tensor pred = uniform_random_points(250, 100 + seed) * 1.2f;
        pred = at::cat({pred, pred.slice(0, 0, 40)});
        gt = at::cat({gt, gt.slice(0, 10, 30)});
        expect_relative_near(psnr_d1(pred, gt), oracle_psnr(pred, gt), 1e-9);
    }
}

TEST(Psnr, InvariantToPointOrderTranslationAndScale) {
    at::Tensor gt = uniform_random_points(400, 21);
    at::Tensor pred = gt + 0.05f * uniform_random_points(400, 22);
    double reference = psnr_d1(pred, gt);
    EXPECT_NEAR(psnr_d1(test::permuted(pred, 1), test::permuted(gt, 2)), reference, 1e-9);
    at::Tensor offset = at::tensor({10.f, -3.f, 7.f});
    // Tolerance: float32 rounding of the moved coordinates.
    EXPECT_NEAR(psnr_d1(pred * 4.f + offset, gt * 4.f + offset), reference, 1e-3);
}

// A GT of one point has no extent to scale to 1023: only the translation applies, so the
// one-way MSE is the raw squared distance, 1 here.
TEST(Psnr, SinglePointGroundTruthIsOnlyTranslated) {
    at::Tensor gt = cloud({1, 1, 1});
    at::Tensor pred = cloud({1, 1, 2});
    expect_relative_near(psnr_d1(pred, gt), 10 * std::log10(3 * 1023.0 * 1023.0), 1e-9);
}

TEST(Psnr, RejectsEmptyCloudsAndWrongShapes) {
    at::Tensor points = uniform_random_points(10, 3);
    EXPECT_THROW(psnr_d1(at::empty({0, 3}), points), InputError);
    EXPECT_THROW(psnr_d1(points, at::empty({0, 3})), InputError);
    EXPECT_THROW(psnr_d1(points.view({30}), points), InputError);
}

}  // namespace
}  // namespace pumeta
