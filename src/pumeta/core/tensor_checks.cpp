#include "pumeta/core/tensor_checks.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"

namespace pumeta {

std::string shape_string(const at::Tensor& tensor) {
    if (!tensor.defined()) return "undefined";
    std::string text = "[";
    for (int64_t d = 0; d < tensor.dim(); ++d)
        text += (d ? ", " : "") + std::to_string(tensor.size(d));
    return text + "]";
}

void check_points(const at::Tensor& points, const std::string& what, int64_t min_count) {
    if (!points.defined()) throw_input_error(what, "point tensor is undefined");
    if (points.dim() != 2 || points.size(1) != 3)
        throw_input_error(what, "expected points of shape [N,3], found {}", shape_string(points));
    if (points.scalar_type() != at::kFloat)
        throw_input_error(what, "expected float32 points, found {}",
                          std::string(c10::toString(points.scalar_type())));
    if (points.size(0) < min_count)
        throw_input_error(what, "needs at least {} points, found {}", min_count, points.size(0));
}

void check_batched_points(const at::Tensor& points, const std::string& what) {
    if (!points.defined() || points.dim() != 3 || points.size(2) != 3)
        throw_input_error(what, "expected points of shape [B,N,3], found {}", shape_string(points));
    if (points.scalar_type() != at::kFloat && points.scalar_type() != at::kDouble)
        throw_input_error(what, "expected floating-point points, found {}",
                          std::string(c10::toString(points.scalar_type())));
}

void check_faces(const at::Tensor& faces, int64_t num_vertices, const std::string& what) {
    if (!faces.defined() || faces.dim() != 2 || faces.size(1) != 3 ||
        faces.scalar_type() != at::kLong)
        throw_input_error(what, "expected int64 faces of shape [F,3]");
    if (faces.numel() == 0) return;
    int64_t lo = faces.min().item<int64_t>();
    int64_t hi = faces.max().item<int64_t>();
    if (lo < 0 || hi >= num_vertices)
        throw_input_error(what, "face index out of range: found [{}, {}], mesh has {} vertices", lo,
                          hi, num_vertices);
}

}  // namespace pumeta
