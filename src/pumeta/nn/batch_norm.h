// Batch normalisation that runs from explicit parameters and buffers (channels-last), so that
// MAML's fast weights can replace gamma and beta. Statistics are taken per channel over every
// leading dimension, as TensorFlow's batch_norm on NHWC maps.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <map>
#include <string>

#include "pumeta/nn/parameters.h"

namespace pumeta {

/// Adds the trainable `prefix.gamma` (ones) and `prefix.beta` (zeros), float32 [channels], to
/// `params`, and the running statistics `prefix.running_mean` (zeros) and `prefix.running_var`
/// (ones), float32 [channels], to `buffers` (TensorFlow's initial values).
void add_batch_norm(ParamMap& params, ParamMap& buffers, const std::string& prefix,
                    int64_t channels);

/// Train mode: (x - mean) / sqrt(var + eps) · gamma + beta with the mean and biased variance
/// of x itself, x [..., C] -> same shape. Only plain ATen ops, so differentiable twice (through
/// the statistics too). Buffers are neither read nor written.
at::Tensor batch_norm_batch_stats(const at::Tensor& x, const ParamMap& params,
                                  const std::string& prefix, double eps);

/// Inference mode: the same with `prefix.running_mean` and `prefix.running_var` from `buffers`
/// (converted to x's dtype and device).
at::Tensor batch_norm_running_stats(const at::Tensor& x, const ParamMap& params,
                                    const ParamMap& buffers, const std::string& prefix, double eps);

/// The 1x1 convolution `conv` (`conv`.weight [Cout,Cin], `conv`.bias) followed by the batch
/// norm `norm` on its running statistics, as one convolution for inference:
/// weight·s and (bias − mean)·s + beta with s = gamma / sqrt(var + eps), in `type` (the buffers
/// converted). conv1x1_weights(x, folded.weight, folded.bias) equals
/// batch_norm_running_stats(conv1x1(x, params, conv), ...) up to rounding.
struct FoldedConv {
    at::Tensor weight, bias;
};
FoldedConv fold_batch_norm(const ParamMap& params, const ParamMap& buffers, const std::string& conv,
                           const std::string& norm, double eps, at::ScalarType type);

/// running ← (1 − momentum) · running + momentum · batch, for the mean and the unbiased
/// variance of x [..., C] (as TensorFlow's fused batch norm and PyTorch do). No gradient.
/// InputError unless 0 <= momentum <= 1 and x has at least two rows.
void update_running_stats(const at::Tensor& x, ParamMap& buffers, const std::string& prefix,
                          double momentum);

/// A batch's per-channel statistics: mean and biased variance [C] over `rows` rows, for
/// layers that know them without the rows themselves (nn/point_conv.h).
struct BatchMoments {
    at::Tensor mean;
    at::Tensor var;
    int64_t rows = 0;
};
using BatchMomentsMap = std::map<std::string, BatchMoments>;

/// The moments of x [..., C].
BatchMoments batch_moments(const at::Tensor& x);

/// update_running_stats from the moments (the variance made unbiased with rows / (rows − 1)).
void update_running_stats(const BatchMoments& batch, ParamMap& buffers, const std::string& prefix,
                          double momentum);

}  // namespace pumeta
