#include "pumeta/nn/repulsion_loss.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/nn/graph.h"

namespace pumeta {

namespace {

// Squared distances [B,N,k] of every point to its k nearest others.
at::Tensor nearest_sq_distances(const at::Tensor& points, int64_t neighbors, const char* what) {
    check_batched_points(points, what);
    if (neighbors < 1) throw_input_error(what, "neighbors must be >= 1, found {}", neighbors);
    if (points.size(1) <= neighbors)
        throw_input_error(what, "needs more than {} points per batch element, found {}", neighbors,
                          points.size(1));
    at::Tensor nearest;
    {
        at::NoGradGuard no_grad;
        at::Tensor query = points.detach().to(at::kFloat).contiguous();
        // Each point is its own nearest (distance 0); with exact duplicates another copy may
        // come first instead, which leaves the same distances.
        nearest = knn(query, query, neighbors + 1).indices.narrow(2, 1, neighbors);
    }
    return (gather_neighbors(points, nearest) - points.unsqueeze(2)).pow(2).sum(-1);
}

}  // namespace

at::Tensor repulsion_loss(const at::Tensor& points, int64_t neighbors, double h) {
    return at::relu(h - nearest_sq_distances(points, neighbors, "repulsion_loss")).mean();
}

at::Tensor punet_repulsion_loss(const at::Tensor& points, int64_t neighbors, double radius,
                                double h) {
    at::Tensor sq = nearest_sq_distances(points, neighbors, "punet_repulsion_loss");
    at::Tensor distance = sq.clamp_min(1e-12).sqrt();
    return (radius - distance * (-sq / (h * h)).exp()).mean();
}

}  // namespace pumeta
