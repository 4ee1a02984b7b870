// Graphs on batched point features: kNN in feature space and neighbour gathering, the
// building blocks of edge convolutions. Layout is channels-last, [B,N,C].
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// The k nearest neighbours of every point among the other points of its batch element, by
/// squared Euclidean distance in feature space, nearest first, the point itself excluded.
/// features: float [B,N,C]; returns int64 [B,N,k] indices into N. 1 <= k < N.
/// Brute force (one batched matmul and a top-k on [B,N,N]); runs without gradient tracking,
/// since indices are not differentiated.
at::Tensor knn_graph(const at::Tensor& features, int64_t k);

/// Neighbour features: x [B,N,C], idx int64 [B,N,k] -> [B,N,k,C] with
/// out[b,i,j] = x[b, idx[b,i,j]]. Differentiable (twice) with respect to x.
at::Tensor gather_neighbors(const at::Tensor& x, const at::Tensor& idx);

/// Channel-wise maximum over neighbours without materialising [B,N,k,C]:
/// out[b,i,c] = max_j x[b, idx[b,i,j], c]; x [B,N,C], idx int64 [B,N,k] -> [B,N,C].
/// The maximising neighbour is found without gradient tracking (first on ties) and its value
/// picked with an index_select, so the result and its gradients (first and second order)
/// equal those of gather_neighbors(x, idx).amax(2) except that amax splits the gradient among
/// exact ties.
at::Tensor gather_max(const at::Tensor& x, const at::Tensor& idx);

/// Channel-wise maximum over the neighbour dimension of per-edge features:
/// y [B,N,k,C] -> [B,N,C], out[b,i,c] = max_j y[b,i,j,c]. Like gather_max, the maximising edge
/// is found without gradient tracking and its value picked by an index_select, so the
/// backward pass writes one value per output instead of comparing all k·C.
at::Tensor max_over_neighbors(const at::Tensor& y);

}  // namespace pumeta
