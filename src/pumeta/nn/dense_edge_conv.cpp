#include "pumeta/nn/dense_edge_conv.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <cmath>

#include "pumeta/nn/conv.h"
#include "pumeta/nn/graph.h"
#include "pumeta/nn/init.h"

namespace pumeta {

namespace {

std::string block_prefix(const std::string& prefix, int64_t block) {
    return prefix + ".block" + std::to_string(block);
}

// add_edge_conv draws each of its two [out,in] weights with the fan sum in + out; the
// original's one kernel over [x_i, x_j − x_i] has fans 2·in and out. Rescales to that limit.
void match_original_xavier(ParamMap& params, const std::string& name, int64_t drawn,
                           int64_t original) {
    at::NoGradGuard no_grad;
    params.at(name).mul_(std::sqrt(double(drawn) / double(original)));
}

}  // namespace

int64_t add_dense_edge_conv(ParamMap& params, const std::string& prefix,
                            const DenseEdgeConvShape& shape, std::mt19937_64& rng) {
    const int64_t g = shape.growth;
    add_linear(params, prefix + ".layer0", 3, shape.first, /*bias=*/true, rng);
    int64_t channels = shape.first;
    for (int64_t b = 0; b < shape.blocks; ++b) {
        const std::string block = block_prefix(prefix, b);
        int64_t in = shape.first;
        if (b > 0) {
            add_linear(params, block + ".prep", channels, 2 * g, true, rng);
            in = 2 * g;
        }
        add_edge_conv(params, block + ".edge", in, g, rng);
        match_original_xavier(params, block + ".edge.central.weight", in + g, 2 * in + g);
        match_original_xavier(params, block + ".edge.message.weight", in + g, 2 * in + g);
        add_linear(params, block + ".l1", g + in, g, true, rng);
        add_linear(params, block + ".l2", 2 * g + in, g, true, rng);
        channels = (b == 0 ? shape.first : channels) + 3 * g + in;
    }
    return channels;
}

at::Tensor dense_edge_conv(const at::Tensor& x, const ParamMap& params, const std::string& prefix,
                           const DenseEdgeConvShape& shape, int64_t k) {
    const int64_t g = shape.growth;
    k = std::min(k, x.size(1) - 1);
    at::Tensor first = conv1x1(x, params, prefix + ".layer0");  // linear, as the original
    at::Tensor features;
    for (int64_t b = 0; b < shape.blocks; ++b) {
        const std::string block = block_prefix(prefix, b);
        at::Tensor in = b == 0 ? first : at::relu(conv1x1(features, params, block + ".prep"));
        const int64_t c = in.size(-1);
        // The in_i columns of l1 and l2 act per point, not per edge.
        at::Tensor graph = knn_graph(in, k);
        at::Tensor y0 = edge_conv_edges(in, graph, params, block + ".edge");
        const at::Tensor& w1 = param(params, block + ".l1.weight");
        const at::Tensor& w2 = param(params, block + ".l2.weight");
        at::Tensor y1 =
            at::relu(conv1x1_weights(y0, w1.narrow(1, 0, g), {}) +
                     conv1x1_weights(in, w1.narrow(1, g, c), param(params, block + ".l1.bias"))
                         .unsqueeze(2));
        at::Tensor y2 =
            conv1x1_weights(at::cat({y1, y0}, -1), w2.narrow(1, 0, 2 * g), {}) +
            conv1x1_weights(in, w2.narrow(1, 2 * g, c), param(params, block + ".l2.bias"))
                .unsqueeze(2);
        at::Tensor dense = at::cat({max_over_neighbors(at::cat({y2, y1, y0}, -1)), in}, -1);
        // The first block's input appears twice (inside the dense output and again), as in
        // the original's 24 + (24 + 3·24) = 120.
        features = at::cat({dense, b == 0 ? first : features}, -1);
    }
    return features;
}

}  // namespace pumeta
