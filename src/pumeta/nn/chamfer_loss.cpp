#include "pumeta/nn/chamfer_loss.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <limits>
#include <type_traits>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

// Nearest point of each query by exact squared differences. Points are in structure-of-arrays
// layout, processed in blocks of kLanes with a running minimum per lane, so the inner loop
// is branch-free and vectorises; the lanes are reduced at the end (first index on ties).
template <typename scalar_t>
void nearest_cpu(const at::Tensor& queries, const at::Tensor& points_soa, at::Tensor& out) {
    constexpr int64_t kLanes = 16;
    const int64_t num_queries = queries.size(1), num_points = points_soa.size(2);
    const int64_t full = num_points / kLanes * kLanes;
    const scalar_t* q = queries.data_ptr<scalar_t>();
    const scalar_t* p = points_soa.data_ptr<scalar_t>();
    int64_t* result = out.data_ptr<int64_t>();
    at::parallel_for(0, queries.size(0) * num_queries, 64, [&](int64_t begin, int64_t end) {
        for (int64_t row = begin; row < end; ++row) {
            const scalar_t* px = p + (row / num_queries) * 3 * num_points;
            const scalar_t* py = px + num_points;
            const scalar_t* pz = py + num_points;
            const scalar_t qx = q[3 * row], qy = q[3 * row + 1], qz = q[3 * row + 2];
            auto distance = [&](int64_t m) {
                scalar_t dx = px[m] - qx, dy = py[m] - qy, dz = pz[m] - qz;
                return dx * dx + dy * dy + dz * dz;
            };
            // Same-width value and index lanes, selected with masks: vectorisable.
            using index_t = std::conditional_t<sizeof(scalar_t) == 4, int32_t, int64_t>;
            scalar_t best[kLanes];
            index_t best_index[kLanes];
            for (int64_t lane = 0; lane < kLanes; ++lane) {
                best[lane] = std::numeric_limits<scalar_t>::infinity();
                best_index[lane] = index_t(lane);
            }
            for (int64_t start = 0; start < full; start += kLanes) {
                for (int64_t lane = 0; lane < kLanes; ++lane) {
                    scalar_t d = distance(start + lane);
                    index_t mask = -index_t(d < best[lane]);  // all ones where closer
                    best[lane] = d < best[lane] ? d : best[lane];
                    best_index[lane] = (index_t(start + lane) & mask) | (best_index[lane] & ~mask);
                }
            }
            scalar_t nearest = std::numeric_limits<scalar_t>::infinity();
            int64_t nearest_index = 0;
            for (int64_t lane = 0; lane < kLanes; ++lane) {
                if (best[lane] < nearest ||
                    (best[lane] == nearest && int64_t(best_index[lane]) < nearest_index)) {
                    nearest = best[lane];
                    nearest_index = best_index[lane];
                }
            }
            for (int64_t m = full; m < num_points; ++m) {
                scalar_t d = distance(m);
                if (d < nearest) {
                    nearest = d;
                    nearest_index = m;
                }
            }
            result[row] = nearest_index;
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
