#include "pumeta/eval/oracle.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/metrics.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

/// Points on a sphere of radius 3 around (1, 1, 1): the ground truth must follow the input's
/// frame.
at::Tensor shifted_sphere(int64_t n, uint64_t seed) {
    return test::sphere_points(n, seed) * 3.0 + 1.0;
}

TEST(Oracle, AdaptsOnTheGroundTruthInTheInputsFrame) {
    auto model = test::small_pugcn(4);
    at::Tensor input = shifted_sphere(300, 10);
    at::Tensor gt = shifted_sphere(1200, 11);
    UpsampleResult plain = upsample_cloud(*model, input, {});
    UpsampleOptions options;
    options.adaptation.inner.steps = 5;
    options.adaptation.inner.step_size = 0.05;
    UpsampleResult oracle = upsample_with_oracle(*model, input, gt, options);
    EXPECT_EQ(oracle.points.size(0), 1200);
    EXPECT_LT(oracle.loss_after, 0.9 * oracle.loss_before);
    // Fitting the ground truth around each patch brings the whole output closer to it.
    EXPECT_LT(chamfer_distance(oracle.points, gt), chamfer_distance(plain.points, gt));
    // A different task from the self-supervised one.
    UpsampleResult object = upsample_cloud(*model, input, options);
    EXPECT_FALSE(object.points.equal(oracle.points));
    // Two passes (16x with a 4x model) would need a ground truth per pass.
    options.ratio = 16;
    EXPECT_THROW(upsample_with_oracle(*model, input, gt, options), InputError);
}

}  // namespace
}  // namespace pumeta
