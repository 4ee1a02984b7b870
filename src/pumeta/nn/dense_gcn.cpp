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
    EdgeTerms terms = edge_conv_terms(x, params, prefix);
    // y0 is needed per edge as the input of W0, but its maximum over the edges is
    // ReLU(centre + max_j message_j) (ReLU is monotone): one gather-max, no per-edge max.
    at::Tensor y0 = at::relu(gather_neighbors(terms.message, idx) + terms.centre.unsqueeze(2));
    at::Tensor y0_max = at::relu(gather_max(terms.message, idx) + terms.centre);
    at::Tensor y1 = at::relu(conv1x1(y0, params, prefix + ".l0"));
    at::Tensor y1b = at::relu(conv1x1(y1, params, prefix + ".l0"));
    at::Tensor y2 = at::relu(conv1x1(at::cat({y0, y1b}, -1), params, prefix + ".l1"));
    return at::cat({y0_max, y1b.amax(2), y2.amax(2)}, -1);
}

}  // namespace pumeta
