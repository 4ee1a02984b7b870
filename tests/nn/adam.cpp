// Adam's optimiser groups: a parameter's learning-rate scale and its own weight decay.
#include "pumeta/nn/adam.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>

#include "pumeta/core/error.h"

namespace pumeta {
namespace {

ParamMap two_parameters() {
    ParamMap params;
    params["a"] = at::full({4}, 2.0f).requires_grad_(true);
    params["b"] = at::full({4}, 2.0f).requires_grad_(true);
    return params;
}

TEST(Adam, AGroupsLearningRateScaleScalesItsSteps) {
    ParamMap params = two_parameters();
    Adam adam(params, AdamOptions{1e-3});
    adam.set_group("b", OptimizerGroup{10.0, 0.0});
    const at::Tensor grad = at::tensor({0.5f, -1.0f, 2.0f, -0.25f});
    for (int step = 0; step < 3; ++step) adam.step({{"a", grad}, {"b", grad}});
    const at::Tensor moved_a = (params["a"] - 2.0).detach();
    const at::Tensor moved_b = (params["b"] - 2.0).detach();
    // Same gradients, same moments: b moves exactly ten times as far, each step against the
    // gradient's sign by about the learning rate (Adam's steps are about lr in size).
    EXPECT_TRUE(at::allclose(moved_b, moved_a * 10.0, 1e-4, 1e-7));
    for (int64_t i = 0; i < 4; ++i) {
        const double a = moved_a[i].item<double>();
        EXPECT_LT(a * grad[i].item<double>(), 0.0);
        EXPECT_NEAR(std::abs(a), 3e-3, 1e-4);
    }
}

TEST(Adam, AGroupsWeightDecayPullsItsParameterTowardsZero) {
    ParamMap params = two_parameters();
    Adam adam(params, AdamOptions{1e-2});
    adam.set_group("b", OptimizerGroup{1.0, 0.1});
    const at::Tensor zero = at::zeros({4});
    adam.step({{"a", zero}, {"b", zero}});
    // Without a gradient a stays; b's L2 term (0.1·b) is its whole gradient.
    EXPECT_TRUE(at::equal(params["a"].detach(), at::full({4}, 2.0f)));
    EXPECT_TRUE(at::allclose(params["b"].detach(), at::full({4}, 2.0f - 1e-2f), 1e-5, 1e-6));
}

TEST(Adam, AGroupsGradientClipBoundsEachGradientValue) {
    ParamMap params = two_parameters();
    Adam clipped(params, AdamOptions{1e-2});
    clipped.set_group("b", OptimizerGroup{1.0, 0.0, 1.0});
    const at::Tensor grad = at::tensor({0.5f, -3.0f, 20.0f, -0.25f});
    for (int step = 0; step < 2; ++step) clipped.step({{"a", grad}, {"b", grad}});
    // The moments of b saw clamp(g, -1, 1): the same values below 1 in size, and since Adam
    // divides by the gradient's own scale, a constant gradient moves a and b alike.
    EXPECT_TRUE(at::allclose(params["a"].detach(), params["b"].detach(), 1e-5, 1e-6));
    // A changing gradient shows the clip: steps of +20 then -20 cancel in a's first moment
    // exactly as +1 then -1 do in b's, but a second moment 400 times larger shrinks a's step.
    ParamMap other = two_parameters();
    Adam adam(other, AdamOptions{1e-2});
    adam.set_group("b", OptimizerGroup{1.0, 0.0, 1.0});
    adam.step({{"a", at::full({4}, 20.0f)}, {"b", at::full({4}, 20.0f)}});
    adam.step({{"a", at::full({4}, 0.5f)}, {"b", at::full({4}, 0.5f)}});
    const double moved_a = 2.0 - other["a"][0].item<double>();
    const double moved_b = 2.0 - other["b"][0].item<double>();
    EXPECT_GT(moved_b, moved_a);
    // b: m = 0.9·0.1·1 + 0.1·0.5, v = 0.999·0.001·1 + 0.001·0.25, bias-corrected, lr 1e-2.
    const double m1 = 0.1, v1 = 0.001;
    const double m2 = 0.9 * m1 + 0.1 * 0.5, v2 = 0.999 * v1 + 0.001 * 0.25;
    const double second_step = 1e-2 * (m2 / (1 - 0.81)) / (std::sqrt(v2 / (1 - 0.998001)) + 1e-8);
    EXPECT_NEAR(moved_b, 1e-2 + second_step, 1e-6);
}

TEST(Adam, AGroupForAnUnknownParameterIsAnInternalError) {
    ParamMap params = two_parameters();
    Adam adam(params, AdamOptions{});
    EXPECT_THROW(adam.set_group("c", OptimizerGroup{}), InternalError);
}

}  // namespace
}  // namespace pumeta
