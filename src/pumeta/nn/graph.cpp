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

// flat[b,i,c] = position in x (contiguous [B,N,C]) of x[b, idx[b,i,j*], c], j* the first j
// maximising it: one pass over each neighbour row, nothing [B,N,k,C]-sized is written.
template <typename scalar_t>
void argmax_neighbors_cpu(const at::Tensor& x, const at::Tensor& idx, at::Tensor& flat) {
    const int64_t num_points = x.size(1), channels = x.size(2), k = idx.size(2);
    const scalar_t* xs = x.data_ptr<scalar_t>();
    const int64_t* is = idx.data_ptr<int64_t>();
    int64_t* out = flat.data_ptr<int64_t>();
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
                const int64_t base = (batch_base + n) * channels;
                const scalar_t* values = xs + base;
                for (int64_t c = 0; c < channels; ++c) {
                    bool larger = j == 0 || values[c] > best[c];
                    best[c] = larger ? values[c] : best[c];
                    chosen[c] = larger ? base + c : chosen[c];
                }
            }
        }
    });
}

// flat[b,i,c] = position in y (contiguous [B,N,k,C]) of max_j y[b,i,j,c] (first on ties).
template <typename scalar_t>
void argmax_edges_cpu(const at::Tensor& y, at::Tensor& flat) {
    const int64_t k = y.size(2), channels = y.size(3);
    const scalar_t* ys = y.data_ptr<scalar_t>();
    int64_t* out = flat.data_ptr<int64_t>();
    at::parallel_for(0, y.size(0) * y.size(1), 16, [&](int64_t begin, int64_t end) {
        std::vector<scalar_t> best(static_cast<size_t>(channels));
        for (int64_t row = begin; row < end; ++row) {
            int64_t* chosen = out + row * channels;
            for (int64_t j = 0; j < k; ++j) {
                const int64_t base = (row * k + j) * channels;
                const scalar_t* values = ys + base;
                for (int64_t c = 0; c < channels; ++c) {
                    bool larger = j == 0 || values[c] > best[c];
                    best[c] = larger ? values[c] : best[c];
                    chosen[c] = larger ? base + c : chosen[c];
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
    // Results are not views (like at::matmul's), so callers' in-place ops need no CopySlices.
    return at::_unsafe_view(rows.index_select(0, flat_indices(idx, num_points)),
                            {batch, num_points, idx.size(2), channels});
}

at::Tensor gather_max(const at::Tensor& x, const at::Tensor& idx) {
    check_graph(x, idx, "gather_max");
    at::Tensor values = x.contiguous();
    at::Tensor flat;
    {
        at::NoGradGuard no_grad;
        if (x.device().is_cpu()) {
            at::Tensor neighbors = idx.contiguous();
            flat = at::empty(x.sizes(), idx.options());
            AT_DISPATCH_FLOATING_TYPES(x.scalar_type(), "gather_max", [&] {
                argmax_neighbors_cpu<scalar_t>(values.detach(), neighbors, flat);
            });
        } else {
            const int64_t channels = x.size(2);
            at::Tensor best = gather_neighbors(values.detach(), idx).argmax(2);  // [B,N,C]
            at::Tensor rows = idx.gather(2, best) +
                              at::arange(x.size(0), idx.options()).mul_(x.size(1)).view({-1, 1, 1});
            flat = rows * channels + at::arange(channels, idx.options());
        }
    }
    // Picking by flat position: index_select's backward is a 1-D index_add, cheaper than
    // gather's scatter.
    return at::_unsafe_view(values.view(-1).index_select(0, flat.view(-1)), x.sizes());
}

at::Tensor max_over_neighbors(const at::Tensor& y) {
    if (!y.defined() || y.dim() != 4 || y.size(2) < 1 || !at::isFloatingType(y.scalar_type()))
        throw_input_error("max_over_neighbors",
                          "expected floating-point edge features [B,N,k>=1,C], found {}",
                          shape_string(y));
    at::Tensor values = y.contiguous();
    at::Tensor flat;
    {
        at::NoGradGuard no_grad;
        if (y.device().is_cpu()) {
            flat = at::empty({y.size(0), y.size(1), y.size(3)}, y.options().dtype(at::kLong));
            AT_DISPATCH_FLOATING_TYPES(y.scalar_type(), "max_over_neighbors",
                                       [&] { argmax_edges_cpu<scalar_t>(values.detach(), flat); });
        } else {
            const int64_t k = y.size(2), channels = y.size(3);
            at::Tensor best = values.argmax(2);  // [B,N,C]
            at::Tensor rows =
                at::arange(y.size(0) * y.size(1), best.options()).view({y.size(0), y.size(1), 1});
            flat = ((rows * k + best) * channels) + at::arange(channels, best.options());
        }
    }
    return at::_unsafe_view(values.view(-1).index_select(0, flat.view(-1)),
                            {y.size(0), y.size(1), y.size(3)});
}

}  // namespace pumeta
