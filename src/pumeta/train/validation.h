// Validation on held-out patches: a fixed set drawn once, scored by Chamfer distance.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

#include "pumeta/data/patch_set.h"
#include "pumeta/nn/parameters.h"

namespace pumeta {

class Backbone;

struct ValidationSet {
    at::Tensor input;     ///< float32 [V, patch_points, 3]
    at::Tensor gt;        ///< float32 [V, patch_points·r, 3]
    double input_cd = 0;  ///< CD between input and GT: the "return the input" reference
};

/// The first `count` patches of a seeded shuffle of `set` (evenly over meshes), inputs drawn
/// with `sampler`, no augmentation.
ValidationSet make_validation_set(const PatchSet& set, int64_t count, InputSampler sampler,
                                  uint64_t seed);

/// Mean CD (sum of the two mean squared NN distances) of the model's upsampled validation
/// inputs against their GT patches, in the patch frame, evaluated in chunks without gradients.
double validation_cd(const Backbone& model, const ValidationSet& set,
                     const ParamMap* params = nullptr);

/// Mean CD of batched clouds a [V,N,3] vs b [V,M,3] (sum of the two means, per cloud).
double mean_chamfer(const at::Tensor& a, const at::Tensor& b);

}  // namespace pumeta
