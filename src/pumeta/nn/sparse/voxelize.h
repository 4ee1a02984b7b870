// Between continuous points and voxel sites: quantisation onto a grid of a given voxel size
// and voxel centres back.
#pragma once

#include <ATen/core/Tensor.h>

#include "pumeta/nn/sparse/coordinate_set.h"

namespace pumeta {

/// Voxel coordinates of a batch of clouds: points floating [B,N,3] -> int64 [B·N,4] rows
/// (b, floor(x/h), floor(y/h), floor(z/h)), point n of element b at row b·N + n. InputError for
/// a non-positive voxel size or non-finite points.
at::Tensor voxel_coordinates(const at::Tensor& points, double voxel_size);

/// The distinct voxels of `coords` (integer [M,4]) in order of first occurrence, as a
/// stride-1 coordinate set.
CoordinateSetPtr unique_sites(const at::Tensor& coords);

/// unique_sites(voxel_coordinates(points, voxel_size)): the occupied voxels of each element.
CoordinateSetPtr voxelize(const at::Tensor& points, double voxel_size);

/// Voxel centres (x + 0.5)·h, ... of integer sites [M,4] (batch column ignored) -> float32 [M,3].
at::Tensor voxel_centres(const at::Tensor& coords, double voxel_size);

}  // namespace pumeta
