// Nearest-neighbour distances between two clouds, the building block of the point-to-point
// metrics (internal to metrics/).
#pragma once

#include <ATen/core/Tensor.h>

#include <vector>

namespace pumeta {

/// For each point of `from` [N,3], the squared distance to its nearest point of `to` [M,3],
/// M >= 1; any floating dtype and device (not checked here: the public metrics check for
/// float32 first). Returns N doubles, in the order of `from`. The kd-tree (float32) picks the
/// neighbour, then the distance is recomputed in double from the given coordinates, so that
/// metrics summing many of them, or working at pc_error's 0..1023 scale, keep double
/// precision.
std::vector<double> nearest_sq_distances(const at::Tensor& from, const at::Tensor& to);

}  // namespace pumeta
