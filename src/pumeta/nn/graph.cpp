#include "pumeta/nn/graph.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <limits>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

void check_features(const at::Tensor& x, const char* what) {
    if (!x.defined() || x.dim() != 3 || !at::isFloatingType(x.scalar_type()))
        throw_input_error(what, "expected floating-point features of shape [B,N,C], found {}",
                          shape_string(x));
}

void check_graph(const at::Tensor& x, const at::Tensor& idx, const char* what) {
    check_features(x, what);
    if (!idx.defined() || idx.dim() != 3 || idx.scalar_type() != at::kLong ||
        idx.size(0) != x.size(0) || idx.size(1) != x.size(1) || idx.size(2) < 1)
        throw_input_error(what,
                          "expected int64 neighbour indices of shape [{}, {}, k>=1], found {}",
                          x.size(0), x.size(1), shape_string(idx));
}

// idx [B,N,k] into N -> flat indices into B*N rows.
at::Tensor flat_indices(const at::Tensor& idx, int64_t num_points) {
    at::Tensor offsets = at::arange(idx.size(0), idx.options()).mul_(num_points).view({-1, 1, 1});
    return (idx + offsets).view(-1);
}

// sel[b,i,c] = idx[b,i,j*] with j* the first j maximising x[b, idx[b,i,j], c]: one pass
// over each neighbour row, nothing [B,N,k,C]-sized is written.
template <typename scalar_t>
void argmax_neighbors_cpu(const at::Tensor& x, const at::Tensor& idx, at::Tensor& sel) {
    const int64_t num_points = x.size(1), channels = x.size(2), k = idx.size(2);
    const scalar_t* xs = x.data_ptr<scalar_t>();
    const int64_t* is = idx.data_ptr<int64_t>();
    int64_t* out = sel.data_ptr<int64_t>();
    at::parallel_for(0, x.size(0) * num_points, 16, [&](int64_t begin, int64_t end) {
        std::vector<scalar_t> best(static_cast<size_t>(channels));
        for (int64_t row = begin; row < end; ++row) {
            const int64_t batch_base = (row / num_points) * num_points;
            const int64_t* neighbors = is + row * k;
            int64_t* chosen = out + row * channels;
            for (int64_t j = 0; j < k; ++j) {
                int64_t n = neighbors[j];
                if (n < 0 || n >= num_points)
                    throw_input_error("gather_max", "neighbour index {} out of range [0, {})", n,
                                      num_points);
                const scalar_t* values = xs + (batch_base + n) * channels;
                if (j == 0) {
                    for (int64_t c = 0; c < channels; ++c) {
                        best[c] = values[c];
                        chosen[c] = n;
                    }
                    continue;
                }
                for (int64_t c = 0; c < channels; ++c) {
                    bool larger = values[c] > best[c];
                    best[c] = larger ? values[c] : best[c];
                    chosen[c] = larger ? n : chosen[c];
                }
            }
        }
    });
}

}  // namespace

at::Tensor knn_graph(const at::Tensor& features, int64_t k) {
    check_features(features, "knn_graph");
    const int64_t num_points = features.size(1);
    if (k < 1 || k >= num_points)
        throw_input_error("knn_graph", "k = {} must be in [1, N) with N = {}", k, num_points);
    at::NoGradGuard no_grad;
    at::Tensor x = features.detach();
    // |x_i - x_j|^2 = |x_i|^2 + |x_j|^2 - 2 x_i.x_j; |x_i|^2 is constant along each row, so
    // it cannot change the ranking and is left out.
    at::Tensor sq_norms = x.pow(2).sum(-1).unsqueeze(1).expand({-1, num_points, -1});
    at::Tensor scores = at::baddbmm(sq_norms, x, x.transpose(1, 2), /*beta=*/1, /*alpha=*/-2);
    scores.diagonal(0, 1, 2).fill_(std::numeric_limits<double>::infinity());
    return std::get<1>(scores.topk(k, -1, /*largest=*/false, /*sorted=*/true));
}

at::Tensor gather_neighbors(const at::Tensor& x, const at::Tensor& idx) {
    check_graph(x, idx, "gather_neighbors");
    const int64_t batch = x.size(0), num_points = x.size(1), channels = x.size(2);
    at::Tensor rows = x.reshape({batch * num_points, channels});
    return rows.index_select(0, flat_indices(idx, num_points))
        .view({batch, num_points, idx.size(2), channels});
}

at::Tensor gather_max(const at::Tensor& x, const at::Tensor& idx) {
    check_graph(x, idx, "gather_max");
    at::Tensor sel;
    {
        at::NoGradGuard no_grad;
        if (x.device().is_cpu()) {
            at::Tensor values = x.detach().contiguous();
            at::Tensor neighbors = idx.contiguous();
            sel = at::empty(x.sizes(), idx.options());
            AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "gather_max", [&] {
                argmax_neighbors_cpu<scalar_t>(values, neighbors, sel);
            });
        } else {
            at::Tensor best = gather_neighbors(x.detach(), idx).argmax(2);  // [B,N,C]
            sel = idx.gather(2, best);
        }
    }
    return x.gather(1, sel);
}

}  // namespace pumeta
