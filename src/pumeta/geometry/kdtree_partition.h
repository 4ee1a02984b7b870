// K-d tree partition of large clouds into parts small enough for one pass of quadratic work
// (PU-Dense's 70,000-point parts; the seed FPS of the patch pipeline).
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <vector>

namespace pumeta {

/// Splits points float32 [N,3] recursively at the median of the axis of largest variance
/// until every part has at most `max_points` points (PU-Dense uses 70,000). Returns each
/// part's point indices (int64, ascending); together they are a partition of [0, N). Parts
/// from one split are separated by a plane: the first half's coordinates along the split axis
/// are <= the second half's. Deterministic. InputError for max_points < 1.
std::vector<at::Tensor> kdtree_partition(const at::Tensor& points, int64_t max_points = 70000);

}  // namespace pumeta
