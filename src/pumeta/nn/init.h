// Seeded parameter initialisation: helpers that ADD fresh leaf tensors to a ParamMap.
#pragma once

#include <cstdint>
#include <random>
#include <string>

#include "pumeta/nn/parameters.h"

namespace pumeta {

/// Adds `name` = float32 [fan_out, fan_in] drawn from Xavier/Glorot uniform
/// U(-a, a), a = sqrt(6 / (fan_in + fan_out)) (TensorFlow's xavier_initializer, which the
/// reference implementations use), as a leaf with requires_grad = true. InternalError if
/// `name` is already present. Values come from `rng` only (no library distribution), so the
/// same seed gives the same weights on every platform.
void add_xavier_uniform(ParamMap& params, const std::string& name, int64_t fan_out, int64_t fan_in,
                        std::mt19937_64& rng);

/// Adds `name` = float32 zeros [size] (biases start at zero, as in TensorFlow).
void add_zeros(ParamMap& params, const std::string& name, int64_t size);

/// Adds a 1x1 convolution / linear layer: `prefix.weight` [out,in] (Xavier) and, when
/// `bias`, `prefix.bias` [out] (zeros).
void add_linear(ParamMap& params, const std::string& prefix, int64_t in, int64_t out, bool bias,
                std::mt19937_64& rng);

/// A uniform double in [0, 1) from the top 53 bits of one draw (portable, unlike
/// std::uniform_real_distribution whose algorithm differs between standard libraries).
inline double uniform01(std::mt19937_64& rng) { return double(rng() >> 11) * 0x1.0p-53; }

}  // namespace pumeta
