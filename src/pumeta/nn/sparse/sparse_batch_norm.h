// Batch normalisation over the active sites of a sparse tensor (MinkowskiBatchNorm): the
// channels-last batch norm of nn/batch_norm on the [M,C] features, with the choice between
// batch and running statistics made by the caller (MAML adapts with batch statistics).
#pragma once

#include <ATen/core/Tensor.h>

#include <string>

#include "pumeta/nn/parameters.h"
#include "pumeta/nn/sparse/sparse_tensor.h"

namespace pumeta {

struct BatchNormContext {
    /// Normalise with the statistics of the sites at hand (training, adaptation); otherwise
    /// with the running statistics in `running`.
    bool batch_statistics = true;
    /// Buffers `prefix.running_mean` and `prefix.running_var` [C] (needed without batch
    /// statistics).
    const ParamMap* running = nullptr;
    /// When set (with batch statistics), each layer moves these running statistics towards its
    /// batch's with `momentum` (layers with fewer than 2 sites are skipped).
    ParamMap* update = nullptr;
    double momentum = 0.1;
    double eps = 1e-5;
};

/// Per channel (x − mean) / sqrt(var + eps) · gamma + beta over the sites of x, with
/// `prefix.gamma` and `prefix.beta` from `params` (see add_batch_norm in nn/batch_norm.h).
/// Differentiable twice, through the batch statistics too.
SparseTensor sparse_batch_norm(const SparseTensor& x, const ParamMap& params,
                               const std::string& prefix, const BatchNormContext& context);

}  // namespace pumeta
