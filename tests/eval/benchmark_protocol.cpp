// The published PU-GAN/PU1K protocol against independent computations: brute-force distances
// after normalising each cloud here, hand-computed cases, and point-to-face distances to meshes
// whose distances are known.
#include "pumeta/eval/benchmark_protocol.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "metrics/metric_oracles.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::brute_force_sq_distances;

/// Centroid to 0, farthest point to 1, in double (independent of geometry/normalize).
at::Tensor own_unit_sphere(const at::Tensor& points) {
    at::Tensor p = points.to(at::kDouble);
    p = p - p.mean(0);
    return p / p.norm(2, 1).max();
}

/// The cube [-a, a]³ as 12 triangles.
TriangleMesh cube(double a) {
    std::vector<float> v;
    for (int i = 0; i < 8; ++i)
        for (int axis = 0; axis < 3; ++axis)
            v.push_back(static_cast<float>((i >> axis) & 1 ? a : -a));
    const std::vector<int64_t> f = {0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1,
                                    2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3};
    return {at::tensor(v, at::kFloat).view({8, 3}).clone(),
            at::tensor(f, at::kLong).view({12, 3}).clone()};
}

TEST(BenchmarkProtocol, CdAndHdMatchBruteForceOnEachCloudsOwnUnitSphere) {
    // Clouds of different centres and scales: the protocol removes both before comparing.
    const at::Tensor pred = uniform_random_points(300, 1) * 3.0 + 5.0;
    const at::Tensor gt = uniform_random_points(700, 2) * 0.2 - 1.0;
    const at::Tensor p = own_unit_sphere(pred), g = own_unit_sphere(gt);
    const std::vector<double> forward = brute_force_sq_distances(p, g);
    const std::vector<double> backward = brute_force_sq_distances(g, p);
    const BenchmarkScores scores = score_benchmark_object(pred, gt);
    const double cd = test::mean(forward) + test::mean(backward);
    EXPECT_NEAR(scores.cd, cd, 1e-5 * cd);
    const double hd = std::sqrt(std::max(test::max(forward), test::max(backward)));
    EXPECT_NEAR(scores.hd, hd, 1e-5 * hd);
    const double legacy = test::max(forward) + test::max(backward);
    EXPECT_NEAR(scores.hd_legacy, legacy, 1e-5 * legacy);
    EXPECT_FALSE(scores.p2f.defined());
}

TEST(BenchmarkProtocol, HandComputedCase) {
    // Both clouds already on their unit spheres (centroid 0, radius 1). Pred's middle point is
    // 1 from the GT: pred->GT mean 1/3, GT->pred 0; HD 1; PU-GCN's sum of squared maxima 1.
    const at::Tensor gt = test::cloud({-1, 0, 0, 1, 0, 0});
    const at::Tensor pred = test::cloud({-1, 0, 0, 0, 0, 0, 1, 0, 0});
    const BenchmarkScores scores = score_benchmark_object(pred, gt);
    EXPECT_NEAR(scores.cd, 1.0 / 3.0, 1e-7);
    EXPECT_NEAR(scores.hd, 1.0, 1e-7);
    EXPECT_NEAR(scores.hd_legacy, 1.0, 1e-7);
}

TEST(BenchmarkProtocol, AShiftedScaledCopyScoresZeroButItsP2fSeesTheShift) {
    // GT on the plane z = 0 of a square mesh; pred is the GT scaled by 2 and lifted by 0.3.
    const at::Tensor gt = uniform_random_points(400, 3) * at::tensor({1.f, 1.f, 0.f});
    const at::Tensor pred = gt * 2.0 + at::tensor({0.f, 0.f, 0.3f});
    const TriangleMesh square = {
        test::cloud({-3, -3, 0, 3, -3, 0, 3, 3, 0, -3, 3, 0}),
        at::tensor(std::vector<int64_t>{0, 1, 2, 0, 2, 3}, at::kLong).view({2, 3})};
    const BenchmarkScores scores = score_benchmark_object(pred, gt, &square);
    EXPECT_NEAR(scores.cd, 0.0, 1e-10);
    EXPECT_NEAR(scores.hd, 0.0, 1e-5);
    // P2F in the mesh's own coordinates, as the published tables: pred's height 0.3 over the
    // plane, whatever the GT's radius, and pred's in-plane doubling does not leave the (large)
    // square.
    const at::Tensor g = gt.to(at::kDouble);
    const double radius = (g - g.mean(0)).norm(2, 1).max().item<double>();
    ASSERT_GT(std::abs(radius - 1.0), 0.1);  // a frame change would show
    ASSERT_EQ(scores.p2f.size(0), 400);
    EXPECT_NEAR(scores.p2f.min().item<double>(), 0.3, 1e-5);
    EXPECT_NEAR(scores.p2f.max().item<double>(), 0.3, 1e-5);
}

TEST(BenchmarkProtocol, P2fToACubeMatchesKnownDistances) {
    // The GT is the corners of the cube [-a, a]³ with a = 1/√3: centroid 0, radius 1, so the
    // GT's frame is the identity and the distances below are exact.
    const double a = 1.0 / std::sqrt(3.0);
    const TriangleMesh mesh = cube(a);
    const at::Tensor gt = mesh.vertices;
    const float fa = static_cast<float>(a);
    const at::Tensor pred = test::cloud({0, 0, fa + 0.2f,                    // above a face
                                         fa + 0.1f, fa + 0.1f, 0,            // beside an edge
                                         0, 0, 0,                            // the centre, inside
                                         fa, 0.1f, -0.2f,                    // on a face
                                         fa + 0.1f, fa + 0.2f, fa + 0.2f});  // beyond a corner
    const BenchmarkScores scores = score_benchmark_object(pred, gt, &mesh);
    const std::vector<double> expected = {0.2, 0.1 * std::sqrt(2.0), a, 0.0, 0.3};
    ASSERT_EQ(scores.p2f.size(0), 5);
    for (size_t i = 0; i < expected.size(); ++i)
        EXPECT_NEAR(scores.p2f[i].item<double>(), expected[i], 1e-6) << "point " << i;
}

TEST(BenchmarkProtocol, TallyAveragesCdOverObjectsAndPoolsP2fOverPoints) {
    BenchmarkScores first, second, third;
    first.cd = 1e-3;
    first.hd = 0.02;
    first.hd_legacy = 4e-4;
    first.p2f = at::tensor({0.1, 0.2, 0.3}, at::kDouble);
    second.cd = 3e-3;
    second.hd = 0.04;
    second.hd_legacy = 8e-4;
    second.p2f = at::tensor({0.5, 0.7, 0.9, 1.1, 1.3, 1.5, 1.7}, at::kDouble);
    third.cd = 2e-3;  // no mesh: counts for CD and HD only
    BenchmarkTally tally;
    EXPECT_TRUE(std::isnan(tally.cd()));
    EXPECT_TRUE(std::isnan(tally.p2f_mean()));
    for (const BenchmarkScores* s : {&first, &second, &third}) tally.add(*s);
    EXPECT_EQ(tally.objects(), 3);
    EXPECT_EQ(tally.objects_with_mesh(), 2);
    EXPECT_EQ(tally.p2f_points(), 10);
    EXPECT_NEAR(tally.cd(), 2e-3, 1e-15);
    EXPECT_NEAR(tally.hd(), 0.02, 1e-15);
    EXPECT_NEAR(tally.hd_legacy(), 4e-4, 1e-15);
    // Pooled over the ten values, not the mean of the two objects' means.
    const at::Tensor all = at::cat({first.p2f, second.p2f});
    EXPECT_NEAR(tally.p2f_mean(), all.mean().item<double>(), 1e-12);
    EXPECT_NEAR(tally.p2f_std(), all.std(/*unbiased=*/false).item<double>(), 1e-12);
    EXPECT_GT(std::abs(tally.p2f_mean() - 0.5 * (0.2 + 1.1)), 0.1);
}

TEST(BenchmarkProtocol, EmptyOrMalformedCloudsAreInputErrors) {
    const at::Tensor gt = uniform_random_points(10, 4);
    EXPECT_TRUE(test::throws_input_error(
        [&] {
            score_benchmark_object(at::empty({0, 3}, at::kFloat), gt);
        },
        {"prediction"}));
    EXPECT_TRUE(test::throws_input_error(
        [&] {
            score_benchmark_object(gt, at::zeros({5, 2}, at::kFloat));
        },
        {"ground truth"}));
}

}  // namespace
}  // namespace pumeta
