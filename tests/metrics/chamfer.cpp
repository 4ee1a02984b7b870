// Chamfer and Hausdorff distances against brute force and a hand-computed fixture.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "metrics/metric_oracles.h"
#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/metrics.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::brute_force_sq_distances;
using test::cloud;
using test::max;
using test::mean;

TEST(Chamfer, MatchesBruteForceOnRandomCloudsOfDifferentSizes) {
    const std::vector<std::pair<int64_t, int64_t>> sizes = {
        {1, 1}, {1, 50}, {37, 5}, {200, 350}, {1000, 700}};
    uint64_t seed = 1;
    for (auto [n_pred, n_gt] : sizes) {
        at::Tensor pred = uniform_random_points(n_pred, seed++);
        at::Tensor gt = uniform_random_points(n_gt, seed++);
        std::vector<double> forward = brute_force_sq_distances(pred, gt);
        std::vector<double> backward = brute_force_sq_distances(gt, pred);
        SCOPED_TRACE(testing::Message() << n_pred << " vs " << n_gt << " points");
        EXPECT_NEAR(chamfer_distance(pred, gt), mean(forward) + mean(backward), 1e-12);
        EXPECT_NEAR(hausdorff_distance(pred, gt), std::sqrt(std::max(max(forward), max(backward))),
                    1e-12);
        EXPECT_NEAR(hausdorff_distance_legacy(pred, gt), max(forward) + max(backward), 1e-12);
    }
}

// gt = {(0,0,0), (2,0,0), (0,2,0), (0,0,2)}, pred = {(0,0,0), (2,0,0), (1,1,0)}.
// pred -> gt squared NN distances: 0, 0, 2 (from (1,1,0) to (0,0,0), (2,0,0) or (0,2,0));
//   mean 2/3, max 2.
// gt -> pred: 0, 0, 2 ((0,2,0) to (1,1,0)), 4 ((0,0,2) to (0,0,0)); mean 3/2, max 4.
// CD = 2/3 + 3/2 = 13/6; HD = sqrt(max(2, 4)) = 2; HD legacy = 2 + 4 = 6.
TEST(Chamfer, HandComputedFixture) {
    at::Tensor gt = cloud({0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 2});
    at::Tensor pred = cloud({0, 0, 0, 2, 0, 0, 1, 1, 0});
    EXPECT_DOUBLE_EQ(chamfer_distance(pred, gt), 13.0 / 6.0);
    EXPECT_DOUBLE_EQ(hausdorff_distance(pred, gt), 2.0);
    EXPECT_DOUBLE_EQ(hausdorff_distance_legacy(pred, gt), 6.0);
    // Chamfer is symmetric; a duplicated point counts twice (unlike PSNR, see psnr.cpp):
    // pred -> gt becomes (0 + 0 + 2 + 2) / 4 = 1, so CD = 1 + 3/2.
    EXPECT_DOUBLE_EQ(chamfer_distance(gt, pred), 13.0 / 6.0);
    at::Tensor duplicated = cloud({0, 0, 0, 2, 0, 0, 1, 1, 0, 1, 1, 0});
    EXPECT_DOUBLE_EQ(chamfer_distance(duplicated, gt), 2.5);
}

TEST(Chamfer, IdenticalCloudsGiveZero) {
    at::Tensor points = uniform_random_points(300, 7);
    EXPECT_EQ(chamfer_distance(points, points), 0.0);
    EXPECT_EQ(hausdorff_distance(points, points), 0.0);
    EXPECT_EQ(hausdorff_distance_legacy(points, points), 0.0);
}

TEST(Chamfer, InvariantToPointOrder) {
    at::Tensor pred = uniform_random_points(500, 11);
    at::Tensor gt = uniform_random_points(400, 12);
    at::Tensor pred_perm = test::permuted(pred, 13);
    at::Tensor gt_perm = test::permuted(gt, 14);
    EXPECT_NEAR(chamfer_distance(pred_perm, gt_perm), chamfer_distance(pred, gt), 1e-14);
    EXPECT_EQ(hausdorff_distance(pred_perm, gt_perm), hausdorff_distance(pred, gt));
    EXPECT_EQ(hausdorff_distance_legacy(pred_perm, gt_perm), hausdorff_distance_legacy(pred, gt));
}

TEST(Chamfer, RejectsEmptyCloudsAndWrongShapes) {
    at::Tensor points = uniform_random_points(10, 3);
    EXPECT_THROW(chamfer_distance(at::empty({0, 3}), points), InputError);
    EXPECT_THROW(chamfer_distance(points, at::empty({0, 3})), InputError);
    EXPECT_THROW(hausdorff_distance(at::zeros({4, 2}), points), InputError);
    EXPECT_THROW(hausdorff_distance_legacy(points, points.to(at::kDouble)), InputError);
}

}  // namespace
}  // namespace pumeta
