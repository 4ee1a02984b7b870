// Chamfer distance as a training loss (PU-GCN's definition).
#pragma once

#include <ATen/core/Tensor.h>

namespace pumeta {

/// For each query, the index of its nearest point (squared Euclidean distance, first index on
/// ties): queries [B,N,3], points [B,M,3] -> int64 [B,N]. No gradient tracking.
at::Tensor nearest_point_indices(const at::Tensor& queries, const at::Tensor& points);

/// mean over the batch of 0.5·mean_i min_j |p_i - t_j|² + 0.5·mean_j min_i |p_i - t_j|²
/// (squared distances, as PU-GCN's `chamfer`). pred [B,N,3], target [B,M,3] (float or
/// double); returns a scalar.
/// The nearest neighbours are found without gradient tracking; the distances to them are then
/// recomputed from coordinate differences, which is exact (no |a|²+|b|²-2ab cancellation) and
/// differentiable twice, with the same gradients as a min over all pairs.
at::Tensor chamfer_loss(const at::Tensor& pred, const at::Tensor& target);

}  // namespace pumeta
