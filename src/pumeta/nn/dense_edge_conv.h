// The dense EdgeConv feature extractor of PU-GAN (Li et al., ICCV 2019), which Dis-PU reuses
// and MPU (Wang et al., CVPR 2019) runs per level with other widths: a linear first layer,
// then blocks of dynamic-graph EdgeConv with dense (DenseNet-style) connections, each block's
// output stacked onto everything before it.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <random>
#include <string>

#include "pumeta/nn/parameters.h"

namespace pumeta {

/// Widths of a dense EdgeConv feature extractor.
struct DenseEdgeConvShape {
    /// Width of the first (linear, 3 -> first) layer: PU-GAN and MPU 24; Dis-PU the growth.
    int64_t first = 24;
    /// Growth rate: every layer inside a block adds this many channels; the 1x1 compression
    /// before blocks 2.. has 2·growth outputs. PU-GAN 24, MPU 12.
    int64_t growth = 24;
    /// Blocks (>= 1). PU-GAN and MPU 4.
    int64_t blocks = 4;

    /// Output channels: 3·growth + 2·first after block 1, + 5·growth per further block
    /// (PU-GAN 480, MPU 264).
    int64_t channels() const { return 3 * growth + 2 * first + 5 * growth * (blocks - 1); }
};

/// Adds the extractor's parameters under `prefix`: `prefix.layer0` (3 -> first), and per block
/// b `prefix.block<b>.prep` (b > 0: channels so far -> 2·growth), `prefix.block<b>.edge`
/// (an edge convolution in -> growth, see add_edge_conv), `prefix.block<b>.l1`
/// (growth + in -> growth) and `prefix.block<b>.l2` (2·growth + in -> growth), all with
/// biases. Weights are Xavier-uniform with TensorFlow's fans: the edge convolution's limit
/// counts its [x_i, x_j − x_i] kernel as one (fan 2·in + growth), as the originals.
/// Returns shape.channels().
int64_t add_dense_edge_conv(ParamMap& params, const std::string& prefix,
                            const DenseEdgeConvShape& shape, std::mt19937_64& rng);

/// Runs the extractor on x [B,N,3] -> [B,N,shape.channels()]:
///   f0 = layer0(x) (no activation);
///   block b on in = (b == 0 ? f0 : ReLU(prep(features))), on the kNN graph of `in` itself
///   (k nearest other points in feature space, a dynamic graph; k = min(k, N − 1)):
///     y0 = ReLU(EdgeConv(in)), y1 = ReLU(l1 [y0, in_i]), y2 = l2 [y1, y0, in_i] (linear),
///     dense = [max_j y2, max_j y1, max_j y0, in_i];
///   features = [dense, b == 0 ? f0 : features].
/// Differentiable twice with respect to x and the parameters.
at::Tensor dense_edge_conv(const at::Tensor& x, const ParamMap& params, const std::string& prefix,
                           const DenseEdgeConvShape& shape, int64_t k);

}  // namespace pumeta
