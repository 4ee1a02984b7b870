// Grad-PU's Point3DConv in train mode without its per-edge batch norms. The layer, for the
// k neighbours j of each point i (edges e = (i, j), offsets d_e = p_j - p_i, features f):
//   out_i = sum_j relu(BN_post(W_post (relu(BN_delta(W_delta d_e)) ⊙ relu(BN_feats(f_j)))))
// with every BN on the statistics of the batch's edges. Composed directly, each BN keeps a
// mean, a variance, a normalised copy and their backward temporaries of the edge tensors
// ([B,M,k,C], 67 MB per channel block at the original's training batch): about half of a
// training step. Every statistic here comes from small moments instead, exactly:
//   BN_feats: f_j only varies by point, so the edge statistics are the point statistics
//     weighted by each point's in-degree, and BN then ReLU run per point before the gather;
//   BN_delta: W_delta d_e is linear in the fixed offsets, so its mean and variance follow
//     from the offsets' mean and 3x3 covariance;
//   BN_post: W_post x_e is linear in the product x_e, so they follow from x's mean and C x C
//     second moment (one matrix product as large as the convolution itself).
// Each BN then folds into its convolution's weights; the convolutions' biases cancel in it.
#pragma once

#include <ATen/ATen.h>

#include <string>

#include "pumeta/nn/batch_norm.h"
#include "pumeta/nn/parameters.h"

namespace pumeta {

/// The fixed part of a Point3DConv graph: neighbour indices, the edges' mean offset [3], the
/// offsets centred on it [E,3] and their covariance [3,3], each point's share of the edges
/// [B,M,1] (in-degree / E). Differentiable with respect to the points.
struct PointConvGraph {
    at::Tensor idx;
    at::Tensor offset_mean;
    at::Tensor centred_offsets;
    at::Tensor offset_covariance;
    at::Tensor edge_share;
};

/// The graph of points [B,M,3] with neighbour indices idx int64 [B,M,k] (within each patch).
PointConvGraph point_conv_graph(const at::Tensor& points, const at::Tensor& idx);

/// The layer's output [B,M,C] in train mode from the per-point features f [B,M,C] (the
/// `prefix.feats` convolution already applied), with `prefix.delta.weight` [C,3],
/// `prefix.post.weight` [C,C] and the batch norms `prefix.{feats,delta,post}.bn` (gamma and
/// beta). Equal, with its first and second derivatives, to the direct composition with
/// batch_norm_batch_stats on the gathered edge tensors (tests/nn/point_conv.cpp); the
/// convolutions' biases do not reach it (batch norm removes them there too). With `moments`,
/// also the statistics of each batch norm's input (biases included) under its name, for the
/// running statistics.
at::Tensor point_conv_batch_stats(const at::Tensor& features, const PointConvGraph& graph,
                                  const ParamMap& params, const std::string& prefix, double eps,
                                  BatchMomentsMap* moments = nullptr);

}  // namespace pumeta
