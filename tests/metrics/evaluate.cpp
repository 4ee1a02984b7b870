// evaluate(): the metrics in GT's frame, pinned on a hand-computed fixture and checked for
// invariance to moving, scaling and reordering the inputs.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>

#include "metrics/metric_oracles.h"
#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/metrics.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::cloud;

void expect_relative_near(double actual, double expected, double tolerance) {
    EXPECT_NEAR(actual, expected, tolerance * std::abs(expected)) << "expected " << expected;
}

void expect_same_report(const MetricReport& actual, const MetricReport& expected,
                        double tolerance) {
    expect_relative_near(actual.cd, expected.cd, tolerance);
    expect_relative_near(actual.hd, expected.hd, tolerance);
    expect_relative_near(actual.hd_legacy, expected.hd_legacy, tolerance);
    expect_relative_near(actual.psnr, expected.psnr, tolerance);
    ASSERT_EQ(actual.p2f.has_value(), expected.p2f.has_value());
    if (actual.p2f) expect_relative_near(*actual.p2f, *expected.p2f, tolerance);
    EXPECT_EQ(actual.n_pred, expected.n_pred);
    EXPECT_EQ(actual.n_gt, expected.n_gt);
}

// The fixture of chamfer.cpp and psnr.cpp: gt = {(0,0,0), (2,0,0), (0,2,0), (0,0,2)},
// pred = {(0,0,0), (2,0,0), (1,1,0)}; raw CD 13/6, HD 2, HD legacy 6, PSNR 10 log10(8).
// GT's bounding box is [0,2]^3, centre (1,1,1); every GT point is sqrt(3) from it, so the
// frame scales lengths by 1/sqrt(3) and squared lengths by 1/3:
// CD = 13/18, HD = 2/sqrt(3), HD legacy = 2; PSNR is scale-invariant.
// Mesh: the triangle (2,0,0), (0,2,0), (0,0,2) on the plane x + y + z = 2. (0,0,0) is
// 2/sqrt(3) from it (foot (2/3,2/3,2/3), inside), (2,0,0) and (1,1,0) lie on it:
// raw P2F = 2/(3 sqrt(3)), in the frame 2/9.
TEST(Evaluate, HandComputedFixtureInGroundTruthFrame) {
    at::Tensor gt = cloud({0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 2});
    at::Tensor pred = cloud({0, 0, 0, 2, 0, 0, 1, 1, 0});
    TriangleMesh mesh{cloud({2, 0, 0, 0, 2, 0, 0, 0, 2}),
                      at::tensor({0, 1, 2}, at::kLong).view({1, 3})};
    MetricReport report = evaluate(pred, gt, &mesh);
    expect_relative_near(report.cd, 13.0 / 18.0, 1e-6);
    expect_relative_near(report.hd, 2 / std::sqrt(3.0), 1e-6);
    expect_relative_near(report.hd_legacy, 2.0, 1e-6);
    expect_relative_near(report.psnr, 10 * std::log10(8.0), 1e-6);
    ASSERT_TRUE(report.p2f.has_value());
    expect_relative_near(*report.p2f, 2.0 / 9.0, 1e-6);
    EXPECT_EQ(report.n_pred, 3);
    EXPECT_EQ(report.n_gt, 4);

    // Moving and scaling everything together changes nothing.
    at::Tensor offset = at::tensor({10.f, -3.f, 5.f});
    TriangleMesh moved_mesh{mesh.vertices * 7.f + offset, mesh.faces};
    expect_same_report(evaluate(pred * 7.f + offset, gt * 7.f + offset, &moved_mesh), report, 1e-6);
    EXPECT_FALSE(evaluate(pred, gt).p2f.has_value());
}

TEST(Evaluate, InvariantToTranslationScaleAndPointOrder) {
    at::Tensor gt = uniform_random_points(600, 1) * at::tensor({1.f, 0.5f, 0.2f});
    at::Tensor pred = uniform_random_points(900, 2) * at::tensor({1.1f, 0.5f, 0.25f});
    // Triangles over consecutive GT points, in GT's coordinates like a real mesh.
    TriangleMesh mesh{gt, at::arange(600, at::kLong).view({200, 3})};
    MetricReport report = evaluate(pred, gt, &mesh);
    for (auto [scale, shift] : {std::pair{0.01f, 3.f}, std::pair{250.f, -40.f}}) {
        at::Tensor offset = at::tensor({shift, 2 * shift, -shift});
        TriangleMesh moved_mesh{mesh.vertices * scale + offset, mesh.faces};
        SCOPED_TRACE(testing::Message() << "scale " << scale << ", shift " << shift);
        // Tolerance: float32 rounding of the moved coordinates.
        expect_same_report(evaluate(pred * scale + offset, gt * scale + offset, &moved_mesh),
                           report, 1e-4);
    }
    expect_same_report(evaluate(test::permuted(pred, 3), test::permuted(gt, 4), &mesh), report,
                       1e-9);
}

// The prediction is measured in GT's frame, never normalised on its own: a prediction twice
// too large would score perfectly otherwise.
TEST(Evaluate, PredictionIsNotNormalisedOnItsOwn) {
    at::Tensor gt = uniform_random_points(300, 5);
    at::Tensor centered = gt - (std::get<0>(gt.min(0)) + std::get<0>(gt.max(0))) / 2;
    EXPECT_EQ(evaluate(centered, centered).cd, 0.0);
    EXPECT_GT(evaluate(centered * 2.f, centered).cd, 0.1);
    EXPECT_GT(evaluate(centered + 0.5f, centered).hd, 0.2);
}

TEST(Evaluate, RejectsEmptyCloudsWrongShapesAndBadMeshes) {
    at::Tensor points = uniform_random_points(10, 3);
    EXPECT_THROW(evaluate(at::empty({0, 3}), points), InputError);
    EXPECT_THROW(evaluate(points, at::empty({0, 3})), InputError);
    EXPECT_THROW(evaluate(points.view({5, 6}), points), InputError);
    EXPECT_THROW(evaluate(points, points.to(at::kDouble)), InputError);
    TriangleMesh bad_faces{points, at::tensor({0, 1, 10}, at::kLong).view({1, 3})};
    EXPECT_THROW(evaluate(points, points, &bad_faces), InputError);
}

}  // namespace
}  // namespace pumeta
