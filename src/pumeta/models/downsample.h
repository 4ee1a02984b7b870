// The training-pair downsamplers shared by backbones: dense patches -> sparse inputs. They
// also build X↓ from X for test-time adaptation, so they must reproduce the input pattern.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <string>

namespace pumeta {

/// Names accepted by downsample_points, for messages: "fps, random, nonuniform".
const char* downsampler_names();

/// InputError "<context>: unknown downsampler '<name>' (expected fps, random, nonuniform)"
/// unless `name` is one of them.
void check_downsampler(const std::string& name, const std::string& context);

/// Keeps m of the M points of each batch element: dense float32 [B,M,3] -> [B,m,3].
///   "fps":        farthest point sampling from each element's first point (seed unused);
///   "random":     a uniform random subset (in index order);
///   "nonuniform": the PU-GAN non-uniform index sampler applied to the points sorted by
///                 distance to a random seed point (denser around some places).
/// Each batch element gets its own seed drawn from `seed`. InputError when m > M or m < 1.
at::Tensor downsample_points(const at::Tensor& dense, int64_t m, const std::string& method,
                             uint64_t seed);

}  // namespace pumeta
