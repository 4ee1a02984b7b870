// Dot-product attention over all points of a batch element, computed in blocks of queries so
// that the O(M·N) score matrix never exists at once in a forward pass without gradients.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// out[b,i] = Σ_j softmax_j(scale · q[b,i]·k[b,j]) v[b,j]
/// q [B,M,D], k [B,N,D], v [B,N,C] (same floating dtype and device) -> [B,M,C].
/// Queries are processed in blocks of max(1, max_scores / (B·N)) rows, so a forward pass
/// without gradient tracking holds at most about max_scores scores (plus their softmax) at a
/// time. With gradient tracking each block's softmax is kept for the backward pass, B·M·N
/// values in all: the blocks then bound only the transient tensors.
/// Plain ATen ops: differentiable twice. InputError for mismatched shapes or max_scores < 1.
at::Tensor blocked_attention(const at::Tensor& q, const at::Tensor& k, const at::Tensor& v,
                             double scale, int64_t max_scores);

}  // namespace pumeta
