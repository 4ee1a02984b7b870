// Point-wise and edge convolutions that run from an explicit ParamMap (so MAML's fast
// weights can replace the module's own). Channels-last: features [B,N,C] or [B,N,k,C].
// Only plain ATen ops: every layer is differentiable twice.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <random>
#include <string>

#include "pumeta/nn/parameters.h"

namespace pumeta {

/// 1x1 convolution (a linear map on the last dimension): x [...,Cin] -> [...,Cout] with
/// `prefix.weight` [Cout,Cin] and, when present in `params`, `prefix.bias` [Cout].
/// No activation.
at::Tensor conv1x1(const at::Tensor& x, const ParamMap& params, const std::string& prefix);

/// conv1x1 with explicit weight [Cout,Cin] and bias [Cout] (undefined: none), for layers that
/// use slices or combinations of stored weights.
at::Tensor conv1x1_weights(const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias);

/// Adds the parameters of an edge convolution Cin -> Cout:
///   `prefix.central.weight` [Cout,Cin] (no bias), `prefix.message.weight` [Cout,Cin],
///   `prefix.message.bias` [Cout]
/// (PU-GCN's "central" and "message" 1x1 convolutions).
void add_edge_conv(ParamMap& params, const std::string& prefix, int64_t in, int64_t out,
                   std::mt19937_64& rng);

/// The per-point terms of an edge convolution with parameters under `prefix`:
///   centre = (W_c - W_m) x + b,  message = W_m x,  both [B,N,Cout] for x [B,N,Cin],
/// so that W_c x_i + W_m (x_j - x_i) + b = centre_i + message_j.
struct EdgeTerms {
    at::Tensor centre;
    at::Tensor message;
};
EdgeTerms edge_conv_terms(const at::Tensor& x, const ParamMap& params, const std::string& prefix);

/// Per-edge features of an edge convolution:
///   y[b,i,j] = ReLU(W_c x_i + W_m (x_j - x_i) + b),  j = idx[b,i,:]
/// x [B,N,Cin], idx int64 [B,N,k] -> [B,N,k,Cout]. Computed as ReLU(A_i + M_j) with
/// A = (W_c - W_m) x + b and M = W_m x per point, so the matmuls run per point, not per edge.
at::Tensor edge_conv_edges(const at::Tensor& x, const at::Tensor& idx, const ParamMap& params,
                           const std::string& prefix);

/// An edge convolution followed by a max over the neighbours: max_j y[b,i,j] -> [B,N,Cout].
/// Since ReLU is monotone, max_j ReLU(A_i + M_j) = ReLU(A_i + max_j M_j): nothing per edge is
/// computed beyond one gather-max (see gather_max).
at::Tensor edge_conv(const at::Tensor& x, const at::Tensor& idx, const ParamMap& params,
                     const std::string& prefix);

}  // namespace pumeta
