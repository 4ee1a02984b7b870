// The two noise protocols of the noisy test inputs (docs/data.md, "Test cases"): relative
// (a percentage of the cloud's spread) and absolute (a fixed sigma).
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// "Relative" protocol (PU-Dense): p += N(0,1) * sigma_axis * percent / 100 per axis, where
/// sigma_axis is the cloud's standard deviation along that axis. points: float32 [N,3].
at::Tensor add_relative_noise(const at::Tensor& points, double percent, uint64_t seed);

/// "Absolute" protocol (PU-GCN/Grad-PU), for unit-sphere normalised input:
/// p += clamp(sigma * N(0,1), -clip, clip) per coordinate.
at::Tensor add_absolute_noise(const at::Tensor& points, double sigma, uint64_t seed,
                              double clip = 0.03);

}  // namespace pumeta
