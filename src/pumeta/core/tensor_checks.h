// Shape and dtype checks at the entry of every public function taking tensors.
#pragma once

#include <ATen/core/Tensor.h>

#include <string>

namespace pumeta {

/// "[2, 3]" for a tensor of shape 2x3, "undefined" for an undefined tensor.
std::string shape_string(const at::Tensor& tensor);

/// Throws InputError unless `points` is a float32 tensor of shape [N,3] with N >= min_count.
void check_points(const at::Tensor& points, const std::string& what, int64_t min_count = 0);

/// Throws InputError unless `points` is a float32 tensor of shape [B,N,3].
void check_batched_points(const at::Tensor& points, const std::string& what);

/// Throws InputError unless `faces` is an int64 [F,3] tensor with indices in [0, num_vertices).
void check_faces(const at::Tensor& faces, int64_t num_vertices, const std::string& what);

}  // namespace pumeta
