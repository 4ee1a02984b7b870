#include "pumeta/metrics/nearest_distances.h"

#include <ATen/ATen.h>

#include "pumeta/geometry/knn.h"

namespace pumeta {

std::vector<double> nearest_sq_distances(const at::Tensor& from, const at::Tensor& to) {
    // .to() returns its input unchanged when it already has the dtype and device.
    at::Tensor nearest = KdTree(to.to(at::kCPU, at::kFloat))
                             .query(from.to(at::kCPU, at::kFloat).contiguous(), 1)
                             .indices.contiguous();
    at::Tensor queries = from.to(at::kCPU, at::kDouble).contiguous();
    at::Tensor points = to.to(at::kCPU, at::kDouble).contiguous();

    const int64_t count = queries.size(0);
    const double* q = queries.data_ptr<double>();
    const double* p = points.data_ptr<double>();
    const int64_t* index = nearest.data_ptr<int64_t>();
    std::vector<double> sq_distances(count);
    for (int64_t i = 0; i < count; ++i) {
        const double* neighbour = p + 3 * index[i];
        double sum = 0;
        for (int d = 0; d < 3; ++d) {
            double delta = q[3 * i + d] - neighbour[d];
            sum += delta * delta;
        }
        sq_distances[i] = sum;
    }
    return sq_distances;
}

}  // namespace pumeta
