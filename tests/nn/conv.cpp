#include "pumeta/nn/conv.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <random>

#include "pumeta/nn/dense_gcn.h"
#include "pumeta/nn/graph.h"

namespace pumeta {

namespace {

ParamMap to_double(const ParamMap& params, uint64_t seed) {
    // Random values (biases included, which start at zero) so every term is exercised.
    at::Generator gen = at::detail::createCPUGenerator(seed);
    ParamMap out;
    for (const auto& [name, tensor] : params)
        out[name] = at::randn(tensor.sizes(), gen, at::TensorOptions().dtype(at::kDouble))
                        .mul_(0.5)
                        .requires_grad_(true);
    return out;
}

// PU-GCN's original per-edge formulation: the edge feature [x_i, x_j - x_i] through one 1x1
// convolution with weight [W_c, W_m] and bias b, ReLU.
at::Tensor naive_edges(const at::Tensor& x, const at::Tensor& idx, const ParamMap& p,
                       const std::string& prefix) {
    at::Tensor centre = x.unsqueeze(2).expand({-1, -1, idx.size(2), -1});
    at::Tensor neighbours = gather_neighbors(x, idx);
    at::Tensor edge = at::cat({centre, neighbours - centre}, -1);
    at::Tensor weight =
        at::cat({p.at(prefix + ".central.weight"), p.at(prefix + ".message.weight")}, 1);
    return at::relu(at::matmul(edge, weight.t()) + p.at(prefix + ".message.bias"));
}

// DenseGCN exactly as the TensorFlow code writes it, all per edge.
at::Tensor naive_dense_gcn(const at::Tensor& x, const at::Tensor& idx, const ParamMap& p,
                           const std::string& prefix) {
    auto layer = [&](const at::Tensor& in, const std::string& name) {
        return at::relu(at::matmul(in, p.at(name + ".weight").t()) + p.at(name + ".bias"));
    };
    at::Tensor y0 = naive_edges(x, idx, p, prefix);
    at::Tensor y1 = layer(y0, prefix + ".l0");
    at::Tensor y1b = layer(y1, prefix + ".l0");
    at::Tensor y2 = layer(at::cat({y0, y1b}, -1), prefix + ".l1");
    return std::get<0>(at::cat({y0, y1b, y2}, -1).max(2));
}

struct Fixture {
    at::Tensor x, idx;
    ParamMap params;
};

Fixture make_fixture(int64_t in, int64_t k, uint64_t seed,
                     void (*add)(ParamMap&, const std::string&, int64_t, int64_t, std::mt19937_64&),
                     int64_t out) {
    Fixture f;
    at::Generator gen = at::detail::createCPUGenerator(seed);
    f.x = at::randn({2, 24, in}, gen, at::TensorOptions().dtype(at::kDouble)).requires_grad_(true);
    f.idx = knn_graph(f.x, k);
    ParamMap fresh;
    std::mt19937_64 rng(seed);
    add(fresh, "layer", in, out, rng);
    f.params = to_double(fresh, seed + 1);
    return f;
}

std::vector<at::Tensor> grads(const at::Tensor& value, const Fixture& f) {
    std::vector<at::Tensor> inputs = {f.x};
    for (const auto& [name, tensor] : f.params) inputs.push_back(tensor);
    return torch::autograd::grad({value}, inputs);
}

void expect_same_values_and_gradients(const at::Tensor& fast, const at::Tensor& naive,
                                      const Fixture& f) {
    ASSERT_EQ(fast.sizes(), naive.sizes());
    EXPECT_TRUE(at::allclose(fast, naive, 0, 1e-10));
    // A weighted sum so that every output element gets its own gradient weight.
    at::Tensor weights = at::linspace(-1, 1, fast.numel(), fast.options()).view(fast.sizes());
    auto fast_grads = grads((fast * weights).sum(), f);
    auto naive_grads = grads((naive * weights).sum(), f);
    for (size_t i = 0; i < fast_grads.size(); ++i)
        EXPECT_TRUE(at::allclose(fast_grads[i], naive_grads[i], 0, 1e-10)) << "input " << i;
}

}  // namespace

TEST(Conv1x1, IsALinearMapOnTheLastDimensionWithOptionalBias) {
    ParamMap p;
    p["a.weight"] = at::tensor({1., 2., 3., 4., 5., 6.}, at::kDouble).view({2, 3});
    p["a.bias"] = at::tensor({10., 20.}, at::kDouble);
    p["b.weight"] = p["a.weight"];
    at::Tensor x = at::tensor({1., 0., -1., 2., 1., 0.}, at::kDouble).view({1, 2, 3});
    at::Tensor expected = at::tensor({-2., -2., 4., 13.}, at::kDouble).view({1, 2, 2});
    EXPECT_TRUE(conv1x1(x, p, "b").equal(expected));
    EXPECT_TRUE(conv1x1(x, p, "a").equal(expected + at::tensor({10., 20.}, at::kDouble)));
}

TEST(EdgeConv, FastFormulationEqualsPerEdgeFormulationWithGradients) {
    Fixture f = make_fixture(5, 6, 11, add_edge_conv, 7);
    expect_same_values_and_gradients(edge_conv_edges(f.x, f.idx, f.params, "layer"),
                                     naive_edges(f.x, f.idx, f.params, "layer"), f);
    expect_same_values_and_gradients(edge_conv(f.x, f.idx, f.params, "layer"),
                                     std::get<0>(naive_edges(f.x, f.idx, f.params, "layer").max(2)),
                                     f);
}

TEST(EdgeConv, ParameterShapes) {
    ParamMap p;
    std::mt19937_64 rng(0);
    add_edge_conv(p, "e", 3, 32, rng);
    ASSERT_EQ(p.size(), 3u);
    EXPECT_EQ(p.at("e.central.weight").sizes(), (std::vector<int64_t>{32, 3}));
    EXPECT_EQ(p.at("e.message.weight").sizes(), (std::vector<int64_t>{32, 3}));
    EXPECT_EQ(p.at("e.message.bias").sizes(), (std::vector<int64_t>{32}));
    EXPECT_EQ(count_parameters(p), 224);  // PU-GCN's head: 2·3·32 + 32
}

TEST(DenseGcn, EqualsThePerEdgeReferenceWithGradients) {
    Fixture f = make_fixture(6, 5, 21, add_dense_gcn, 4);
    at::Tensor fast = dense_gcn(f.x, f.idx, f.params, "layer");
    EXPECT_EQ(fast.size(2), 12);
    expect_same_values_and_gradients(fast, naive_dense_gcn(f.x, f.idx, f.params, "layer"), f);
}

TEST(DenseGcn, DilatedIndicesWorkAsGraph) {
    // PU-GCN's second path uses every 2nd of the 2k nearest: a strided view of the graph.
    Fixture f = make_fixture(6, 8, 31, add_dense_gcn, 4);
    at::Tensor dilated = f.idx.slice(2, 0, 8, 2);
    expect_same_values_and_gradients(dense_gcn(f.x, dilated, f.params, "layer"),
                                     naive_dense_gcn(f.x, dilated.contiguous(), f.params, "layer"),
                                     f);
}

}  // namespace pumeta
