// PU-GCN's DenseGCN with three layers, the unit of each Inception DenseGCN path.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <random>
#include <string>

#include "pumeta/nn/parameters.h"

namespace pumeta {

/// Adds the parameters of a DenseGCN with `channels` inputs and growth rate `growth`:
/// an edge convolution `prefix` (see add_edge_conv) channels -> growth, `prefix.l0`
/// growth -> growth and `prefix.l1` 2·growth -> growth (weights and biases).
void add_dense_gcn(ParamMap& params, const std::string& prefix, int64_t channels, int64_t growth,
                   std::mt19937_64& rng);

/// DenseGCN as in PU-GCN's official code, on the edges given by idx int64 [B,N,k]:
///   y0  = ReLU(W_c x_i + W_m (x_j - x_i) + b)    (edge convolution, per edge)
///   y1  = ReLU(W0 y0 + b0)
///   y1' = ReLU(W0 y1 + b0)                        (the SAME W0 applied twice, as the original)
///   y2  = ReLU(W1 [y0, y1'] + b1)
///   out = max over the k edges of [y0, y1', y2]
/// x [B,N,C] -> [B,N,3·growth].
at::Tensor dense_gcn(const at::Tensor& x, const at::Tensor& idx, const ParamMap& params,
                     const std::string& prefix);

}  // namespace pumeta
