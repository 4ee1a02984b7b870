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

TEST(Adam, AGroupForAnUnknownParameterIsAnInternalError) {
    ParamMap params = two_parameters();
    Adam adam(params, AdamOptions{});
    EXPECT_THROW(adam.set_group("c", OptimizerGroup{}), InternalError);
}

}  // namespace
}  // namespace pumeta
