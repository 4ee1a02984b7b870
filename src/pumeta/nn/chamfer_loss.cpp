#include "pumeta/nn/chamfer_loss.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

// Squared distances of one query to all points in structure-of-arrays layout (vectorisable),
// then the first minimum.
template <typename scalar_t>
void nearest_cpu(const at::Tensor& queries, const at::Tensor& points_soa, at::Tensor& out) {
    const int64_t num_queries = queries.size(1), num_points = points_soa.size(2);
    const scalar_t* q = queries.data_ptr<scalar_t>();
    const scalar_t* p = points_soa.data_ptr<scalar_t>();
    int64_t* result = out.data_ptr<int64_t>();
    at::parallel_for(0, queries.size(0) * num_queries, 64, [&](int64_t begin, int64_t end) {
        std::vector<scalar_t> distances(static_cast<size_t>(num_points));
        for (int64_t row = begin; row < end; ++row) {
            const scalar_t* px = p + (row / num_queries) * 3 * num_points;
            const scalar_t* py = px + num_points;
            const scalar_t* pz = py + num_points;
            const scalar_t qx = q[3 * row], qy = q[3 * row + 1], qz = q[3 * row + 2];
            for (int64_t m = 0; m < num_points; ++m) {
                scalar_t dx = px[m] - qx, dy = py[m] - qy, dz = pz[m] - qz;
                distances[m] = dx * dx + dy * dy + dz * dz;
            }
            auto nearest = std::min_element(distances.begin(), distances.end());
            result[row] = nearest - distances.begin();
        }
    });
}

}  // namespace

at::Tensor nearest_point_indices(const at::Tensor& queries, const at::Tensor& points) {
    check_batched_points(queries, "nearest_point_indices (queries)");
    check_batched_points(points, "nearest_point_indices (points)");
    if (queries.size(0) != points.size(0) || points.size(1) < 1)
        throw_input_error("nearest_point_indices", "cannot match queries {} with points {}",
                          shape_string(queries), shape_string(points));
    at::NoGradGuard no_grad;
    at::Tensor q = queries.detach().contiguous();
    at::Tensor p = points.detach().to(q.scalar_type());
    if (q.device().is_cpu()) {
        at::Tensor out = at::empty({q.size(0), q.size(1)}, q.options().dtype(at::kLong));
        at::Tensor soa = p.transpose(1, 2).contiguous();  // [B,3,M]
        AT_DISPATCH_FLOATING_TYPES(q.scalar_type(), "nearest_point_indices",
                                   [&] { nearest_cpu<scalar_t>(q, soa, out); });
        return out;
    }
    // Other devices: batched |q-p|² as q.q + p.p - 2 q.p, chunked to bound the [b,N,M] block.
    const int64_t per_chunk = std::max<int64_t>(1, (int64_t(1) << 26) / (q.size(1) * p.size(1)));
    std::vector<at::Tensor> parts;
    for (int64_t start = 0; start < q.size(0); start += per_chunk) {
        at::Tensor qc = q.narrow(0, start, std::min(per_chunk, q.size(0) - start));
        at::Tensor pc = p.narrow(0, start, qc.size(0));
        at::Tensor d = at::baddbmm(pc.pow(2).sum(-1).unsqueeze(1), qc, pc.transpose(1, 2), 1, -2);
        parts.push_back(d.argmin(-1));
    }
    return at::cat(parts, 0);
}

at::Tensor chamfer_loss(const at::Tensor& pred, const at::Tensor& target) {
    check_batched_points(pred, "chamfer_loss (prediction)");
    check_batched_points(target, "chamfer_loss (target)");
    if (pred.size(0) != target.size(0) || pred.size(1) < 1 || target.size(1) < 1)
        throw_input_error("chamfer_loss", "cannot compare prediction {} with target {}",
                          shape_string(pred), shape_string(target));
    auto nearest_sq_distance = [](const at::Tensor& from, const at::Tensor& to) {
        at::Tensor nearest = nearest_point_indices(from, to).unsqueeze(-1).expand({-1, -1, 3});
        return (from - to.gather(1, nearest)).pow(2).sum(-1);  // [B,N]
    };
    // Both directions have a fixed count per batch element, so the mean over the batch of the
    // per-element means is the mean over all points.
    return 0.5 * nearest_sq_distance(pred, target).mean() +
           0.5 * nearest_sq_distance(target, pred).mean();
}

}  // namespace pumeta
