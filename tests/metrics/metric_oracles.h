// Independent oracles and small helpers shared by the metrics tests.
#pragma once

#include <ATen/ATen.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

namespace pumeta::test {

/// Squared distance from each point of `from` to its nearest point of `to`, by an O(N*M)
/// double-precision loop (independent of the library's kd-tree).
inline std::vector<double> brute_force_sq_distances(const at::Tensor& from, const at::Tensor& to) {
    at::Tensor a = from.to(at::kDouble).contiguous(), b = to.to(at::kDouble).contiguous();
    auto pa = a.accessor<double, 2>();
    auto pb = b.accessor<double, 2>();
    std::vector<double> result(a.size(0), std::numeric_limits<double>::infinity());
    for (int64_t i = 0; i < a.size(0); ++i) {
        for (int64_t j = 0; j < b.size(0); ++j) {
            double sum = 0;
            for (int d = 0; d < 3; ++d) sum += (pa[i][d] - pb[j][d]) * (pa[i][d] - pb[j][d]);
            result[i] = std::min(result[i], sum);
        }
    }
    return result;
}

inline double mean(const std::vector<double>& values) {
    return std::accumulate(values.begin(), values.end(), 0.0) / values.size();
}

inline double max(const std::vector<double>& values) {
    return *std::max_element(values.begin(), values.end());
}

/// float32 [N,3] from a flat list of coordinates.
inline at::Tensor cloud(const std::vector<float>& xyz) {
    return at::tensor(xyz, at::kFloat).view({-1, 3}).clone();
}

/// The rows of `points` in a seeded random order.
inline at::Tensor permuted(const at::Tensor& points, uint64_t seed) {
    std::vector<int64_t> order(points.size(0));
    std::iota(order.begin(), order.end(), 0);
    std::mt19937_64 rng(seed);
    std::shuffle(order.begin(), order.end(), rng);
    return points.index_select(0, at::tensor(order, at::kLong));
}

}  // namespace pumeta::test
