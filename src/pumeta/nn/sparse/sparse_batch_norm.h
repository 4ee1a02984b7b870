// Batch normalisation over the active sites of a sparse tensor (MinkowskiBatchNorm), written
// with plain ATen reductions so that it is differentiable twice, and with the choice between
// batch and running statistics made by the caller (MAML adapts with batch statistics).
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <string>

#include "pumeta/nn/parameters.h"

namespace pumeta {

struct BatchNormContext {
    /// Normalise with the statistics of the sites at hand (training, adaptation); otherwise
    /// with the running statistics in `running`.
    bool batch_statistics = true;
    /// Buffers `prefix.running_mean` and `prefix.running_var` [C] (needed without batch
    /// statistics).
    const ParamMap* running = nullptr;
    /// When set, receives each layer's batch mean and unbiased variance as
    /// `prefix.running_mean` / `prefix.running_var` (detached), to update the running ones.
    ParamMap* observed = nullptr;
    double eps = 1e-5;
};

/// Adds `prefix.weight` (ones) and `prefix.bias` (zeros) [channels] to `params`, and
/// `prefix.running_mean` (zeros) and `prefix.running_var` (ones) to `buffers`.
void add_batch_norm(ParamMap& params, ParamMap& buffers, const std::string& prefix,
                    int64_t channels);

/// (x − mean) / sqrt(var + eps) · weight + bias per channel, x [M,C]; under batch statistics
/// the biased variance over the M sites (as torch's BatchNorm in training).
at::Tensor sparse_batch_norm(const at::Tensor& x, const ParamMap& params, const std::string& prefix,
                             const BatchNormContext& context);

/// running ← (1 − momentum)·running + momentum·observed for every observed statistic
/// (PyTorch's convention: momentum 0.1 weights the new batch by 0.1).
void update_running_statistics(ParamMap& buffers, const ParamMap& observed, double momentum);

}  // namespace pumeta
