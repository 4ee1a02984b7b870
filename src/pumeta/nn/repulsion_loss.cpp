#include "pumeta/nn/repulsion_loss.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/nn/graph.h"

namespace pumeta {

at::Tensor repulsion_loss(const at::Tensor& points, int64_t neighbors, double h) {
    check_batched_points(points, "repulsion_loss");
    if (neighbors < 1)
        throw_input_error("repulsion_loss", "neighbors must be >= 1, found {}", neighbors);
    if (points.size(1) <= neighbors)
        throw_input_error("repulsion_loss", "needs more than {} points per batch element, found {}",
                          neighbors, points.size(1));
    at::Tensor nearest;
    {
        at::NoGradGuard no_grad;
        at::Tensor query = points.detach().to(at::kFloat).contiguous();
        // Each point is its own nearest (distance 0); with exact duplicates another copy may
        // come first instead, which leaves the same distances.
        nearest = knn(query, query, neighbors + 1).indices.narrow(2, 1, neighbors);
    }
    at::Tensor sq = (gather_neighbors(points, nearest) - points.unsqueeze(2)).pow(2).sum(-1);
    return at::relu(h - sq).mean();
}

}  // namespace pumeta
