// Point3DConv from moments against its direct composition (gather, 1x1 convolutions and
// batch norms on the edge tensors): values, first and second derivatives in double precision,
// and the float32 result at a training-sized batch.
#include "pumeta/nn/point_conv.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <random>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/nn/batch_norm.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/graph.h"
#include "pumeta/nn/init.h"

namespace pumeta {
namespace {

constexpr double kEps = 1e-5;

struct Layer {
    at::Tensor points;    // [B,M,3]
    at::Tensor idx;       // [B,M,k]
    at::Tensor features;  // [B,M,C], requires grad
    ParamMap params;
};

Layer make_layer(int64_t batch, int64_t n, int64_t k, int64_t channels, at::ScalarType type,
                 uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    const at::TensorOptions options = at::TensorOptions().dtype(type);
    Layer layer;
    layer.points = at::randn({batch, n, 3}, gen, options);
    std::vector<at::Tensor> indices;
    for (int64_t b = 0; b < batch; ++b)
        indices.push_back(knn(layer.points[b].to(at::kFloat).contiguous(),
                              layer.points[b].to(at::kFloat).contiguous(), k)
                              .indices);
    layer.idx = at::stack(indices);
    // Shifted, as features after a ReLU are: the statistics must not rely on a zero mean.
    layer.features = (at::randn({batch, n, channels}, gen, options) + 0.8).requires_grad_(true);
    auto tensor = [&](std::vector<int64_t> shape, double scale, double shift) {
        return (at::randn(shape, gen, options) * scale + shift).requires_grad_(true);
    };
    for (const char* unit : {"delta", "post"}) {
        const int64_t in = std::string(unit) == "delta" ? 3 : channels;
        layer.params[std::string("l.") + unit + ".weight"] = tensor({channels, in}, 0.5, 0);
        layer.params[std::string("l.") + unit + ".bias"] = tensor({channels}, 0.5, 0);
    }
    for (const char* norm : {"feats", "delta", "post"}) {
        layer.params[std::string("l.") + norm + ".bn.gamma"] = tensor({channels}, 0.3, 1);
        layer.params[std::string("l.") + norm + ".bn.beta"] = tensor({channels}, 0.3, 0);
    }
    return layer;
}

/// The layer as the original composes it, every batch norm on its edge tensor.
at::Tensor direct(const Layer& layer) {
    auto unit = [&](const at::Tensor& x, const std::string& prefix) {
        return at::relu(batch_norm_batch_stats(conv1x1(x, layer.params, prefix), layer.params,
                                               prefix + ".bn", kEps));
    };
    const at::Tensor delta = gather_neighbors(layer.points, layer.idx) - layer.points.unsqueeze(2);
    const at::Tensor neighbours = at::relu(batch_norm_batch_stats(
        gather_neighbors(layer.features, layer.idx), layer.params, "l.feats.bn", kEps));
    return unit(unit(delta, "l.delta") * neighbours, "l.post").sum(2);
}

at::Tensor from_moments(const Layer& layer) {
    return point_conv_batch_stats(layer.features, point_conv_graph(layer.points, layer.idx),
                                  layer.params, "l", kEps);
}

/// The inputs of the derivatives: the features and every parameter the layer reaches
/// (the convolutions' biases do not: batch norm removes them).
std::vector<at::Tensor> inputs(const Layer& layer) {
    std::vector<at::Tensor> out = {layer.features};
    for (const auto& [name, t] : layer.params)
        if (name.find(".bias") == std::string::npos) out.push_back(t);
    return out;
}

TEST(PointConv, ValuesAndGradientsEqualTheDirectComposition) {
    const Layer layer = make_layer(2, 24, 5, 6, at::kDouble, 3);
    const at::Tensor expected = direct(layer), actual = from_moments(layer);
    ASSERT_EQ(actual.sizes(), (std::vector<int64_t>{2, 24, 6}));
    EXPECT_TRUE(at::allclose(actual, expected, 1e-10, 1e-10))
        << (actual - expected).abs().max().item<double>();
    // Some outputs are zero and some not: the ReLUs are live.
    EXPECT_GT(actual.gt(0).sum().item<int64_t>(), 0);

    at::Generator gen = at::detail::createCPUGenerator(4);
    const at::Tensor weights = at::randn(expected.sizes(), gen, expected.options());
    const std::vector<at::Tensor> wrt = inputs(layer);
    auto gradients = [&](const at::Tensor& out) {
        return torch::autograd::grad({(out * weights).sum()}, wrt, {}, true, true);
    };
    const std::vector<at::Tensor> g_direct = gradients(expected), g_moments = gradients(actual);
    for (size_t i = 0; i < wrt.size(); ++i) {
        EXPECT_TRUE(at::allclose(g_moments[i], g_direct[i], 1e-9, 1e-10))
            << "input " << i << ": " << (g_moments[i] - g_direct[i]).abs().max().item<double>();
        EXPECT_GT(g_direct[i].abs().max().item<double>(), 1e-6) << "input " << i;
    }
    // Second order (meta-learning differentiates the inner gradient): the gradient of the
    // gradients' squared norm.
    auto second = [&](const std::vector<at::Tensor>& g) {
        at::Tensor norm = at::zeros({}, expected.options());
        for (const at::Tensor& t : g) norm = norm + t.pow(2).sum();
        return torch::autograd::grad({norm}, wrt, {}, true, false, /*allow_unused=*/true);
    };
    const std::vector<at::Tensor> h_direct = second(g_direct), h_moments = second(g_moments);
    for (size_t i = 0; i < wrt.size(); ++i) {
        ASSERT_TRUE(h_direct[i].defined() && h_moments[i].defined()) << "input " << i;
        EXPECT_TRUE(at::allclose(h_moments[i], h_direct[i], 1e-8, 1e-9))
            << "input " << i << ": " << (h_moments[i] - h_direct[i]).abs().max().item<double>();
    }
}

// The statistics reported for the running averages are those of each batch norm's input on
// the edge tensors, the convolutions' biases included.
TEST(PointConv, ReportedMomentsAreThoseOfEachBatchNormsEdgeInput) {
    const Layer layer = make_layer(2, 20, 4, 5, at::kDouble, 7);
    BatchMomentsMap moments;
    point_conv_batch_stats(layer.features, point_conv_graph(layer.points, layer.idx), layer.params,
                           "l", kEps, &moments);
    const at::Tensor delta = gather_neighbors(layer.points, layer.idx) - layer.points.unsqueeze(2);
    const at::Tensor feats_in = gather_neighbors(layer.features, layer.idx);
    const at::Tensor delta_in = conv1x1(delta, layer.params, "l.delta");
    auto unit = [&](const at::Tensor& x, const std::string& norm) {
        return at::relu(batch_norm_batch_stats(x, layer.params, norm, kEps));
    };
    const at::Tensor post_in = conv1x1(unit(delta_in, "l.delta.bn") * unit(feats_in, "l.feats.bn"),
                                       layer.params, "l.post");
    const std::vector<std::pair<std::string, at::Tensor>> expected = {
        {"l.feats.bn", feats_in}, {"l.delta.bn", delta_in}, {"l.post.bn", post_in}};
    ASSERT_EQ(moments.size(), expected.size());
    for (const auto& [name, x] : expected) {
        const BatchMoments direct_moments = batch_moments(x);
        const BatchMoments& reported = moments.at(name);
        EXPECT_EQ(reported.rows, 2 * 20 * 4) << name;
        EXPECT_TRUE(at::allclose(reported.mean, direct_moments.mean, 1e-10, 1e-12)) << name;
        EXPECT_TRUE(at::allclose(reported.var, direct_moments.var, 1e-10, 1e-12)) << name;
    }
}

// What training runs: float32 at a batch of Grad-PU's size (16 neighbours, 32 channels),
// within float rounding of the direct composition in double precision.
TEST(PointConv, Float32AtATrainingSizedBatchMatchesTheDirectCompositionInDouble) {
    const Layer single = make_layer(4, 512, 16, 32, at::kFloat, 5);
    Layer exact = single;
    exact.points = single.points.to(at::kDouble);
    exact.features = single.features.detach().to(at::kDouble);
    for (auto& [name, t] : exact.params) t = t.detach().to(at::kDouble);
    const at::Tensor expected = direct(exact);
    const at::Tensor actual = from_moments(single).detach().to(at::kDouble);
    const double scale = expected.abs().max().item<double>();
    EXPECT_LT((actual - expected).abs().max().item<double>(), 1e-4 * scale);
}

TEST(PointConv, MismatchedShapesAreNamedErrors) {
    const Layer layer = make_layer(1, 10, 3, 4, at::kFloat, 6);
    const PointConvGraph graph = point_conv_graph(layer.points, layer.idx);
    EXPECT_THROW(
        point_conv_batch_stats(layer.features.slice(1, 0, 9), graph, layer.params, "l", kEps),
        InputError);
    ParamMap wrong = layer.params;
    wrong["l.delta.weight"] = at::zeros({4, 2});
    EXPECT_THROW(point_conv_batch_stats(layer.features, graph, wrong, "l", kEps), InputError);
    EXPECT_THROW(point_conv_graph(layer.points, layer.idx.slice(1, 0, 5)), InputError);
}

}  // namespace
}  // namespace pumeta
