#include "pumeta/geometry/kdtree_partition.h"

#include <ATen/ATen.h>

#include <algorithm>
#include <array>
#include <numeric>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

int64_t widest_axis(const float* p, const std::vector<int64_t>& part) {
    std::array<double, 3> sum{}, square{};
    for (int64_t i : part)
        for (int a = 0; a < 3; ++a) {
            sum[a] += p[3 * i + a];
            square[a] += double(p[3 * i + a]) * p[3 * i + a];
        }
    const double n = double(part.size());
    int64_t best = 0;
    double best_variance = -1;
    for (int a = 0; a < 3; ++a) {
        double variance = square[a] / n - (sum[a] / n) * (sum[a] / n);
        if (variance > best_variance) best_variance = variance, best = a;
    }
    return best;
}

}  // namespace

std::vector<at::Tensor> kdtree_partition(const at::Tensor& points, int64_t max_points) {
    check_points(points, "kdtree partition");
    if (max_points < 1)
        throw_input_error("kdtree partition", "max_points must be >= 1, found {}", max_points);
    at::Tensor contiguous = points.contiguous();
    const float* p = contiguous.data_ptr<float>();
    std::vector<int64_t> all(contiguous.size(0));
    std::iota(all.begin(), all.end(), 0);

    std::vector<at::Tensor> parts;
    // Depth first, lower half first, so that parts come out in spatial order.
    std::vector<std::vector<int64_t>> pending{std::move(all)};
    while (!pending.empty()) {
        std::vector<int64_t> part = std::move(pending.back());
        pending.pop_back();
        if (int64_t(part.size()) <= max_points) {
            std::sort(part.begin(), part.end());
            at::Tensor indices = at::empty({int64_t(part.size())}, at::kLong);
            std::copy(part.begin(), part.end(), indices.data_ptr<int64_t>());
            parts.push_back(indices);
            continue;
        }
        const int64_t axis = widest_axis(p, part);
        auto middle = part.begin() + part.size() / 2;
        std::nth_element(part.begin(), middle, part.end(), [&](int64_t a, int64_t b) {
            float pa = p[3 * a + axis], pb = p[3 * b + axis];
            return pa < pb || (pa == pb && a < b);
        });
        pending.emplace_back(middle, part.end());
        pending.emplace_back(part.begin(), middle);
    }
    return parts;
}

}  // namespace pumeta
