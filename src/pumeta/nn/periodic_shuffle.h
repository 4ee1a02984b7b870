// NodeShuffle's periodic shuffling: turns r·C channels per point into r points of C channels.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>

namespace pumeta {

/// x [B,N,C·r] -> [B,r·N,C]; output point i·r + s (s < r) is child s of input point i, with
/// channels out[b, i·r + s, c] = x[b, i, c·r + s] (PU-GCN's point_shuffler: the r children of
/// a point are consecutive and channel c of every child comes from the block c·r .. c·r+r-1).
/// InputError when the channel count is not a multiple of r.
at::Tensor periodic_shuffle(const at::Tensor& x, int64_t r);

}  // namespace pumeta
