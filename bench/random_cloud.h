// Uniform random points in [-1, 1]³ for the benchmarks (float32 [n,3], seeded).
#pragma once

#include <ATen/ATen.h>

#include <cstdint>
#include <random>

namespace pumeta::bench {

inline at::Tensor random_cloud(int64_t n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> uniform(-1.f, 1.f);
    at::Tensor points = at::empty({n, 3}, at::kFloat);
    float* p = points.data_ptr<float>();
    for (int64_t i = 0; i < 3 * n; ++i) p[i] = uniform(rng);
    return points;
}

}  // namespace pumeta::bench
