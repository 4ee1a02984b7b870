// Gradients by parameter name: zeros for parameters a loss does not reach, or, for the
// supervised trainer, no entry at all, which Adam reads as "leave this one alone".
#include "pumeta/nn/gradients.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/nn/adam.h"

namespace pumeta {
namespace {

ParamMap two_parameters() {
    return {{"used", at::tensor({1.0, 2.0}).requires_grad_(true)},
            {"unused", at::tensor({3.0}).requires_grad_(true)}};
}

TEST(Gradients, UnreachedParametersGetZerosOrNoEntry) {
    ParamMap params = two_parameters();
    at::Tensor loss = (params.at("used") * params.at("used")).sum();
    ParamMap all = gradients(loss, params, false, /*retain_graph=*/true);
    EXPECT_TRUE(all.at("used").allclose(at::tensor({2.0, 4.0})));
    EXPECT_TRUE(all.at("unused").equal(at::zeros({1}, at::kDouble)));
    ParamMap used = used_gradients(loss, params);
    ASSERT_EQ(used.size(), 1u);
    EXPECT_TRUE(used.at("used").allclose(at::tensor({2.0, 4.0})));
    EXPECT_FALSE(used.at("used").requires_grad());
}

TEST(Gradients, AdamLeavesParametersWithoutAGradientAndTheirMomentsAlone) {
    ParamMap params = two_parameters();
    Adam adam(params, AdamOptions{0.1});
    // A step that reaches both, then one that reaches only "used" (a frozen level).
    adam.step(gradients((params.at("used").sum() + params.at("unused").sum()), params));
    const at::Tensor unused_after_first = params.at("unused").detach().clone();
    const at::Tensor moment = adam.state().at("m/unused").clone();
    adam.step(used_gradients(params.at("used").sum(), params));
    EXPECT_TRUE(params.at("unused").equal(unused_after_first));
    EXPECT_TRUE(adam.state().at("m/unused").equal(moment));
    // With a zero gradient instead, Adam would move it on its moments.
    adam.step(gradients(params.at("used").sum(), params));
    EXPECT_FALSE(params.at("unused").equal(unused_after_first));
}

}  // namespace
}  // namespace pumeta
