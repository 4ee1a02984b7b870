#include "pumeta/geometry/noise.h"

#include <ATen/ATen.h>

#include <cmath>
#include <random>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

/// float64 [n,3] standard normal draws from a seeded generator (device-independent results).
at::Tensor standard_normal(int64_t n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    at::Tensor draws = at::empty({n, 3}, at::kDouble);
    double* out = draws.data_ptr<double>();
    for (int64_t i = 0; i < 3 * n; ++i) out[i] = normal(rng);
    return draws;
}

void check_non_negative(double value, const char* name, const char* what) {
    if (!(value >= 0) || !std::isfinite(value))
        throw_input_error(what, "{} must be finite and >= 0, found {}", name, value);
}

}  // namespace

at::Tensor add_relative_noise(const at::Tensor& points, double percent, uint64_t seed) {
    check_points(points, "add_relative_noise");
    check_non_negative(percent, "percent", "add_relative_noise");
    if (points.size(0) == 0) return points.clone();
    // Population standard deviation per axis (numpy's default, as in PU-Dense).
    at::Tensor sigma = points.to(at::kCPU, at::kDouble).std(0, /*unbiased=*/false);
    at::Tensor noise = standard_normal(points.size(0), seed) * sigma * (percent / 100.0);
    return points + noise.to(points.options());
}

at::Tensor add_absolute_noise(const at::Tensor& points, double sigma, uint64_t seed, double clip) {
    check_points(points, "add_absolute_noise");
    check_non_negative(sigma, "sigma", "add_absolute_noise");
    check_non_negative(clip, "clip", "add_absolute_noise");
    at::Tensor noise = (standard_normal(points.size(0), seed) * sigma).clamp(-clip, clip);
    return points + noise.to(points.options());
}

}  // namespace pumeta
