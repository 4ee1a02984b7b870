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
    // The per-edge tensors ([B·N·k, growth] rows) dominate the cost, so none is made that is
    // not needed: ops run in place where their input is not needed by any backward, and
    //  - max_j y0 = ReLU(centre + max_j message_j) (ReLU is monotone): no per-edge max;
    //  - W1 [y0, y1'] = W1a y0 + W1b y1', accumulated into one matmul output (no concat);
    //  - y2 is only needed through its maximum: max_j ReLU(z_j) = ReLU(max_j z_j).
    EdgeTerms terms = edge_conv_terms(x, params, prefix);
    const int64_t batch = x.size(0), points = x.size(1), k = idx.size(2);
    const int64_t growth = terms.message.size(-1);
    auto per_edge = [&](const at::Tensor& rows) { return rows.view({batch, points, k, growth}); };
    at::Tensor y0 = gather_neighbors(terms.message, idx)
                        .add_(terms.centre.unsqueeze(2))
                        .relu_()
                        .view({-1, growth});
    at::Tensor y0_max = (gather_max(terms.message, idx) + terms.centre).relu_();

    const at::Tensor& w0 = param(params, prefix + ".l0.weight");
    const at::Tensor& b0 = param(params, prefix + ".l0.bias");
    at::Tensor y1 = at::addmm(b0, y0, w0.t()).relu_();
    at::Tensor y1b = at::addmm(b0, y1, w0.t()).relu_();  // the same W0 again

    const at::Tensor& w1 = param(params, prefix + ".l1.weight");
    at::Tensor z2 = at::addmm(param(params, prefix + ".l1.bias"), y0, w1.narrow(1, 0, growth).t());
    z2.addmm_(y1b, w1.narrow(1, growth, growth).t());

    return at::cat(
        {y0_max, max_over_neighbors(per_edge(y1b)), max_over_neighbors(per_edge(z2)).relu_()}, -1);
}

}  // namespace pumeta
