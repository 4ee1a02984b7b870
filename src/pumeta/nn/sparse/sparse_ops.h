// Structural operations on sparse tensors: concatenation, addition onto a superset of sites,
// pruning, global pooling. All differentiable (twice) in the features.
#pragma once

#include <ATen/core/Tensor.h>

#include "pumeta/nn/sparse/sparse_tensor.h"

namespace pumeta {

/// Channel concatenation of tensors on the same coordinate set (the same object, as the
/// U-Net's skip connections are): [M,Ca] ++ [M,Cb] -> [M,Ca+Cb].
SparseTensor sparse_cat(const SparseTensor& a, const SparseTensor& b);

/// a + b on a's sites, where every site of b is one of a's (a sum of tensors on different
/// sites is their union; here the union is a). Same channels. InputError otherwise.
SparseTensor add_onto(const SparseTensor& a, const SparseTensor& b);

/// The sites where `keep` (bool [M]) is true, in their order, as a new coordinate set.
SparseTensor prune(const SparseTensor& x, const at::Tensor& keep);

/// Mean of each batch element's features: [B,C] with B = x.coords()->batch_size() (zeros for
/// a batch index without sites).
at::Tensor global_average_pool(const SparseTensor& x);

/// Per-batch-element rows [B,C] copied to every site of that element: [M,C] on `sites`.
SparseTensor broadcast_to_sites(const at::Tensor& per_batch, const CoordinateSetPtr& sites);

}  // namespace pumeta
