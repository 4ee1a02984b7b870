// Blocked attention against a scalar-loop oracle, and block-size invariance of its values and
// of its first and second derivatives.
#include "pumeta/nn/attention.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <cmath>
#include <vector>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

struct Inputs {
    at::Tensor q, k, v;
};

Inputs make_inputs(uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::TensorOptions f64 = at::TensorOptions().dtype(at::kDouble);
    return {at::randn({2, 5, 3}, gen, f64).requires_grad_(true),
            at::randn({2, 7, 3}, gen, f64).requires_grad_(true),
            at::randn({2, 7, 4}, gen, f64).requires_grad_(true)};
}

// out[b,i,c] = Σ_j exp(s_ij) v[b,j,c] / Σ_j exp(s_ij), s_ij = scale · q_i·k_j, with loops.
at::Tensor loop_oracle(const Inputs& in, double scale) {
    at::Tensor qt = in.q.detach(), kt = in.k.detach(), vt = in.v.detach();
    auto q = qt.accessor<double, 3>();
    auto k = kt.accessor<double, 3>();
    auto v = vt.accessor<double, 3>();
    at::Tensor out = at::zeros({2, 5, 4}, at::kDouble);
    auto o = out.accessor<double, 3>();
    for (int b = 0; b < 2; ++b)
        for (int i = 0; i < 5; ++i) {
            std::vector<double> w(7);
            double total = 0;
            for (int j = 0; j < 7; ++j) {
                double s = 0;
                for (int d = 0; d < 3; ++d) s += q[b][i][d] * k[b][j][d];
                w[j] = std::exp(scale * s);
                total += w[j];
            }
            for (int j = 0; j < 7; ++j)
                for (int c = 0; c < 4; ++c) o[b][i][c] += w[j] / total * v[b][j][c];
        }
    return out;
}

std::vector<at::Tensor> derivatives(const Inputs& in, const at::Tensor& out) {
    at::Tensor weights = at::linspace(-1, 1, out.numel(), out.options()).view(out.sizes());
    auto first = torch::autograd::grad({(out * weights).sum()}, {in.q, in.k, in.v}, {}, true, true);
    at::Tensor norm = first[0].pow(2).sum() + first[1].pow(2).sum();
    auto second = torch::autograd::grad({norm}, {in.q, in.k, in.v});
    return {first[0], first[1], first[2], second[0], second[1], second[2]};
}

}  // namespace

TEST(BlockedAttention, MatchesTheSoftmaxFormulaForEveryBlockSize) {
    Inputs in = make_inputs(1);
    at::Tensor expected = loop_oracle(in, 0.6);
    // B·N = 14 scores per query row: blocks of 1, 1, 2 and all 5 rows.
    for (int64_t max_scores : {1, 14, 30, 1000}) {
        at::Tensor out = blocked_attention(in.q, in.k, in.v, 0.6, max_scores);
        EXPECT_EQ(out.sizes(), (std::vector<int64_t>{2, 5, 4}));
        EXPECT_TRUE(at::allclose(out, expected, 1e-12, 1e-12)) << "max_scores " << max_scores;
    }
}

TEST(BlockedAttention, DerivativesDoNotDependOnTheBlockSize) {
    Inputs in = make_inputs(2);
    auto whole = derivatives(in, blocked_attention(in.q, in.k, in.v, 0.5, 1000));
    auto rows = derivatives(in, blocked_attention(in.q, in.k, in.v, 0.5, 14));
    for (size_t i = 0; i < whole.size(); ++i) {
        EXPECT_GT(whole[i].abs().max().item<double>(), 1e-6) << "derivative " << i;
        EXPECT_TRUE(at::allclose(whole[i], rows[i], 1e-11, 1e-11)) << "derivative " << i;
    }
}

TEST(BlockedAttention, InvalidShapesAreInputErrors) {
    at::Tensor q = at::zeros({2, 5, 3}), k = at::zeros({2, 7, 3}), v = at::zeros({2, 7, 4});
    EXPECT_THROW(blocked_attention(q, k.narrow(2, 0, 2), v, 1, 100), InputError);
    EXPECT_THROW(blocked_attention(q, k, v.narrow(1, 0, 6), 1, 100), InputError);
    EXPECT_THROW(blocked_attention(q.narrow(0, 0, 1), k, v, 1, 100), InputError);
    EXPECT_THROW(blocked_attention(q, k, v.to(at::kDouble), 1, 100), InputError);
    EXPECT_THROW(blocked_attention(q, k, v, 1, 0), InputError);
}

}  // namespace pumeta
