#include "pumeta/geometry/normalize.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

/// An anisotropic, off-centre cloud: centroid and bounding-box centre differ.
at::Tensor skewed_cloud() {
    at::Tensor points = uniform_random_points(2000, 1);
    points.select(1, 0).add_(1).pow_(3).mul_(4).add_(10);
    points.select(1, 1).mul_(0.5).sub_(3);
    return points;
}

double max_radius(const at::Tensor& points) {
    return points.to(at::kDouble).norm(2, 1).max().item<double>();
}

TEST(UnitSphereNormalization, CentroidModeCentresAndScalesToRadiusOne) {
    at::Tensor points = skewed_cloud();
    Normalization n = unit_sphere_normalization(points);
    ASSERT_EQ(n.center.sizes(), (at::IntArrayRef{3}));
    ASSERT_EQ(n.center.scalar_type(), at::kFloat);
    EXPECT_TRUE(at::allclose(n.center.to(at::kDouble), points.to(at::kDouble).mean(0), 0, 1e-5));
    at::Tensor normalized = n.apply(points);
    EXPECT_NEAR(max_radius(normalized), 1.0, 1e-6);
    EXPECT_LT(normalized.to(at::kDouble).mean(0).abs().max().item<double>(), 1e-6);
}

TEST(UnitSphereNormalization, BoundingBoxModeCentresTheBox) {
    at::Tensor points = skewed_cloud();
    Normalization n = unit_sphere_normalization(points, CenterMode::kBoundingBox);
    at::Tensor normalized = n.apply(points);
    EXPECT_NEAR(max_radius(normalized), 1.0, 1e-6);
    at::Tensor box_centre = (std::get<0>(normalized.min(0)) + std::get<0>(normalized.max(0))) / 2;
    EXPECT_LT(box_centre.abs().max().item<float>(), 1e-6);
    // Differs from the centroid for this skewed cloud.
    EXPECT_GT((n.center - unit_sphere_normalization(points).center).abs().max().item<float>(), 0.5);
}

TEST(UnitSphereNormalization, InvertUndoesApply) {
    at::Tensor points = skewed_cloud();
    Normalization n = unit_sphere_normalization(points);
    EXPECT_TRUE(at::allclose(n.invert(n.apply(points)), points, 0, 1e-5));
    // A batch [B,N,3] takes the same transform element-wise.
    at::Tensor batch = at::stack({points, points * 2});
    at::Tensor applied = n.apply(batch);
    EXPECT_TRUE(at::equal(applied[0], n.apply(points)));
    EXPECT_TRUE(at::allclose(n.invert(applied), batch, 0, 1e-5));
}

TEST(UnitSphereNormalization, InvariantToTranslationAndScaleOfTheInput) {
    at::Tensor points = skewed_cloud();
    at::Tensor reference = unit_sphere_normalization(points).apply(points);
    for (CenterMode mode : {CenterMode::kCentroid, CenterMode::kBoundingBox}) {
        at::Tensor reference_mode = unit_sphere_normalization(points, mode).apply(points);
        at::Tensor moved = points * 37.5 + at::tensor({-100.f, 3.f, 55.f});
        EXPECT_TRUE(at::allclose(unit_sphere_normalization(moved, mode).apply(moved),
                                 reference_mode, 0, 2e-5));
    }
    EXPECT_FALSE(at::allclose(reference, points, 0, 1e-3));
}

TEST(UnitSphereNormalization, DegenerateCloudsGetScaleOne) {
    at::Tensor single = at::tensor({1.f, 2.f, 3.f}).view({1, 3});
    Normalization n = unit_sphere_normalization(single);
    EXPECT_EQ(n.scale, 1.0);
    EXPECT_TRUE(at::equal(n.apply(single), at::zeros({1, 3})));
    EXPECT_EQ(unit_sphere_normalization(single.expand({5, 3}).contiguous()).scale, 1.0);
    EXPECT_THROW(unit_sphere_normalization(at::zeros({0, 3})), InputError);
    EXPECT_THROW(unit_sphere_normalization(at::zeros({4, 2})), InputError);
    EXPECT_THROW(n.apply(at::zeros({4, 2})), InputError);
}

TEST(Normalization, DefaultIsTheIdentityAndUndefinedCentreIsTheOrigin) {
    at::Tensor points = skewed_cloud();
    EXPECT_TRUE(at::equal(Normalization{}.apply(points), points));
    Normalization scaled{at::Tensor(), 2.0};
    EXPECT_TRUE(at::equal(scaled.apply(points), points * 2));
    EXPECT_TRUE(at::equal(scaled.invert(points * 2), points));
}

}  // namespace
}  // namespace pumeta
