// Batch normalisation from explicit parameters against ATen's own batch_norm (values, first
// and second derivatives, running-statistics update) and hand-computed statistics.
#include "pumeta/nn/batch_norm.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include "pumeta/core/error.h"
#include "pumeta/nn/conv.h"

namespace pumeta {

namespace {

constexpr double kEps = 1e-3;

struct Fixture {
    at::Tensor x;  // [2,5,4,3] channels-last, double
    ParamMap params, buffers;
};

Fixture make_fixture(uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::TensorOptions f64 = at::TensorOptions().dtype(at::kDouble);
    Fixture f;
    f.x = (at::randn({2, 5, 4, 3}, gen, f64) * 2 + 0.7).requires_grad_(true);
    add_batch_norm(f.params, f.buffers, "bn", 3);
    f.params["bn.gamma"] = at::randn({3}, gen, f64).requires_grad_(true);
    f.params["bn.beta"] = at::randn({3}, gen, f64).requires_grad_(true);
    f.buffers["bn.running_mean"] = at::randn({3}, gen, f64);
    f.buffers["bn.running_var"] = at::rand({3}, gen, f64) + 0.5;
    return f;
}

// ATen's reference on the same data as [rows, C].
at::Tensor aten_batch_norm(const Fixture& f, bool training) {
    at::Tensor rows = f.x.reshape({-1, 3});
    at::Tensor out = at::batch_norm(rows, f.params.at("bn.gamma"), f.params.at("bn.beta"),
                                    training ? at::Tensor() : f.buffers.at("bn.running_mean"),
                                    training ? at::Tensor() : f.buffers.at("bn.running_var"),
                                    training, 0.1, kEps, /*cudnn_enabled=*/false);
    return out.view(f.x.sizes());
}

// [d/dx, d/dgamma, d/dbeta] of sum(out · weights) and the gradient of the squared norm of
// those first derivatives (a second-order quantity) with respect to the same inputs.
std::vector<at::Tensor> derivatives(const Fixture& f, const at::Tensor& out) {
    at::Tensor weights = at::linspace(-1, 2, out.numel(), out.options()).view(out.sizes());
    std::vector<at::Tensor> inputs = {f.x, f.params.at("bn.gamma"), f.params.at("bn.beta")};
    auto first = torch::autograd::grad({(out * weights).sum()}, inputs, {}, true, true);
    at::Tensor norm = first[0].pow(2).sum() + first[1].pow(2).sum();
    auto second = torch::autograd::grad({norm}, {f.x, f.params.at("bn.gamma")});
    return {first[0], first[1], first[2], second[0], second[1]};
}

}  // namespace

TEST(BatchNorm, BatchStatisticsMatchATenUpToSecondDerivatives) {
    Fixture f = make_fixture(1);
    at::Tensor ours = batch_norm_batch_stats(f.x, f.params, "bn", kEps);
    at::Tensor reference = aten_batch_norm(f, /*training=*/true);
    EXPECT_TRUE(at::allclose(ours, reference, 1e-12, 1e-12));
    auto a = derivatives(f, ours), b = derivatives(f, reference);
    for (size_t i = 0; i < a.size(); ++i)
        EXPECT_TRUE(at::allclose(a[i], b[i], 1e-10, 1e-10)) << "derivative " << i;
    // The batch's own statistics: per channel, mean beta and standard deviation ~|gamma|.
    at::Tensor rows = ours.detach().reshape({-1, 3});
    EXPECT_TRUE(at::allclose(rows.mean(0), f.params.at("bn.beta").detach(), 0, 1e-12));
}

TEST(BatchNorm, RunningStatisticsMatchATenInference) {
    Fixture f = make_fixture(2);
    at::Tensor ours = batch_norm_running_stats(f.x, f.params, f.buffers, "bn", kEps);
    EXPECT_TRUE(at::allclose(ours, aten_batch_norm(f, /*training=*/false), 1e-12, 1e-12));
    // float32 buffers serve double inputs (converted), as after a dtype change of the model.
    ParamMap float_buffers;
    for (const auto& [name, b] : f.buffers) float_buffers[name] = b.to(at::kFloat);
    at::Tensor converted = batch_norm_running_stats(f.x, f.params, float_buffers, "bn", kEps);
    EXPECT_TRUE(at::allclose(converted, ours, 1e-6, 1e-6));
}

// A convolution and the batch norm after it, folded into one convolution, give the same output.
TEST(BatchNorm, FoldingIntoTheConvolutionBeforeItKeepsTheOutput) {
    Fixture f = make_fixture(2);
    const int64_t channels = f.x.size(-1);
    at::Generator gen = at::detail::createCPUGenerator(5);
    const at::Tensor input = at::randn({4, 6, 5}, gen, at::TensorOptions().dtype(at::kDouble));
    ParamMap params = f.params;
    params["conv.weight"] = at::randn({channels, 5}, gen, at::TensorOptions().dtype(at::kDouble));
    params["conv.bias"] = at::randn({channels}, gen, at::TensorOptions().dtype(at::kDouble));
    const at::Tensor reference =
        batch_norm_running_stats(conv1x1(input, params, "conv"), params, f.buffers, "bn", kEps);
    const FoldedConv folded = fold_batch_norm(params, f.buffers, "conv", "bn", kEps, at::kDouble);
    EXPECT_TRUE(
        at::allclose(conv1x1_weights(input, folded.weight, folded.bias), reference, 1e-10, 1e-10));
}

TEST(BatchNorm, RunningUpdateIsTheMomentumAverageWithUnbiasedVariance) {
    ParamMap params, buffers;
    add_batch_norm(params, buffers, "bn", 2);
    EXPECT_TRUE(buffers.at("bn.running_mean").equal(at::zeros({2})));
    EXPECT_TRUE(buffers.at("bn.running_var").equal(at::ones({2})));
    ParamMap before = buffers;
    // Rows (1, 2) and (3, 6): means (2, 4), unbiased variances (2, 8).
    at::Tensor x = at::tensor({1.f, 2.f, 3.f, 6.f}).view({1, 2, 2});
    update_running_stats(x, buffers, "bn", 0.1);
    EXPECT_TRUE(at::allclose(buffers.at("bn.running_mean"), at::tensor({0.2f, 0.4f})));
    EXPECT_TRUE(at::allclose(buffers.at("bn.running_var"), at::tensor({1.1f, 1.7f})));
    // A copy of the map taken before is a snapshot, not an alias.
    EXPECT_TRUE(before.at("bn.running_mean").equal(at::zeros({2})));

    // ATen's training-mode batch_norm updates its running tensors the same way.
    at::Tensor mean = buffers.at("bn.running_mean").clone();
    at::Tensor var = buffers.at("bn.running_var").clone();
    at::Tensor y = at::randn({7, 2}) * 3 + 1;
    at::batch_norm(y, {}, {}, mean, var, /*training=*/true, 0.25, kEps, false);
    update_running_stats(y, buffers, "bn", 0.25);
    EXPECT_TRUE(at::allclose(buffers.at("bn.running_mean"), mean, 1e-6, 1e-6));
    EXPECT_TRUE(at::allclose(buffers.at("bn.running_var"), var, 1e-6, 1e-6));
}

TEST(BatchNorm, InvalidInputsAreInputErrors) {
    ParamMap params, buffers;
    add_batch_norm(params, buffers, "bn", 3);
    EXPECT_THROW(batch_norm_batch_stats(at::zeros({4, 2}), params, "bn", kEps), InputError);
    EXPECT_THROW(batch_norm_running_stats(at::zeros({4, 5}), params, buffers, "bn", kEps),
                 InputError);
    EXPECT_THROW(update_running_stats(at::zeros({1, 3}), buffers, "bn", 0.1), InputError);
    EXPECT_THROW(update_running_stats(at::zeros({4, 3}), buffers, "bn", 1.5), InputError);
    EXPECT_THROW(add_batch_norm(params, buffers, "bn", 3), InternalError);
}

}  // namespace pumeta
