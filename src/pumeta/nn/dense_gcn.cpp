#include "pumeta/nn/dense_gcn.h"

#include <ATen/ATen.h>

#include "pumeta/nn/conv.h"
#include "pumeta/nn/graph.h"
#include "pumeta/nn/init.h"

namespace pumeta {

void add_dense_gcn(ParamMap& params, const std::string& prefix, int64_t channels, int64_t growth,
                   std::mt19937_64& rng) {
    add_edge_conv(params, prefix, channels, growth, rng);
    add_linear(params, prefix + ".l0", growth, growth, /*bias=*/true, rng);
    add_linear(params, prefix + ".l1", 2 * growth, growth, /*bias=*/true, rng);
}

at::Tensor dense_gcn(const at::Tensor& x, const at::Tensor& idx, const ParamMap& params,
                     const std::string& prefix) {
    // Every tensor below except the per-point terms is per edge ([B,N,k,C]); the step cost is
    // dominated by them, so none is made that is not needed: ReLUs run in place (the matmul
    // outputs are not needed by their backward) and W1 [y0, y1'] is computed as
    // W1a y0 + W1b y1' without concatenating.
    EdgeTerms terms = edge_conv_terms(x, params, prefix);
    at::Tensor y0 = (gather_neighbors(terms.message, idx) + terms.centre.unsqueeze(2)).relu_();
    // max_j y0 = ReLU(centre + max_j message_j) since ReLU is monotone: no per-edge max.
    at::Tensor y0_max = (gather_max(terms.message, idx) + terms.centre).relu_();
    const at::Tensor& w0 = param(params, prefix + ".l0.weight");
    const at::Tensor& b0 = param(params, prefix + ".l0.bias");
    at::Tensor y1 = (conv1x1_weights(y0, w0, b0)).relu_();
    at::Tensor y1b = (conv1x1_weights(y1, w0, b0)).relu_();  // the same W0 again
    const at::Tensor& w1 = param(params, prefix + ".l1.weight");
    const int64_t growth = y0.size(-1);
    at::Tensor y2 =
        conv1x1_weights(y0, w1.narrow(1, 0, growth), param(params, prefix + ".l1.bias"));
    y2 = (y2 + conv1x1_weights(y1b, w1.narrow(1, growth, growth), {})).relu_();
    return at::cat({y0_max, max_over_neighbors(y1b), max_over_neighbors(y2)}, -1);
}

}  // namespace pumeta
