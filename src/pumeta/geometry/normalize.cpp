#include "pumeta/geometry/normalize.h"

#include <ATen/ATen.h>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

namespace {

void check_coordinates(const at::Tensor& points, const char* what) {
    if (!points.defined() || points.dim() < 1 || points.size(-1) != 3 ||
        !at::isFloatingType(points.scalar_type()))
        throw_input_error(what, "expected floating-point points of shape [...,3], found {}",
                          shape_string(points));
}

}  // namespace

at::Tensor Normalization::apply(const at::Tensor& points) const {
    check_coordinates(points, "Normalization::apply");
    if (!center.defined()) return points * scale;
    return (points - center.to(points.options())) * scale;
}

at::Tensor Normalization::invert(const at::Tensor& points) const {
    check_coordinates(points, "Normalization::invert");
    if (!center.defined()) return points / scale;
    return points / scale + center.to(points.options());
}

Normalization unit_sphere_normalization(const at::Tensor& points, CenterMode mode) {
    check_points(points, "unit_sphere_normalization", 1);
    at::Tensor p = points.to(at::kDouble).contiguous();
    at::Tensor center;
    if (mode == CenterMode::kCentroid) {
        // Summed in order: a parallel reduction's partial sums would depend on the thread
        // count, and the centre moves every later result by its rounding.
        const at::Tensor cpu = p.to(at::kCPU);
        const double* xyz = cpu.data_ptr<double>();
        double sum[3] = {0, 0, 0};
        for (int64_t i = 0; i < p.size(0); ++i)
            for (int axis = 0; axis < 3; ++axis) sum[axis] += xyz[3 * i + axis];
        const double n = static_cast<double>(p.size(0));
        center = at::tensor({sum[0] / n, sum[1] / n, sum[2] / n}, at::kDouble).to(p.device());
    } else {
        center = (std::get<0>(p.min(0)) + std::get<0>(p.max(0))) * 0.5;
    }
    Normalization normalization;
    normalization.center = center.to(at::kFloat);
    // The radius about the float32 centre that apply() will subtract, not the exact one.
    const double radius =
        (p - normalization.center.to(at::kDouble)).norm(2, 1).max().item<double>();
    normalization.scale = radius > 0 ? 1.0 / radius : 1.0;
    return normalization;
}

}  // namespace pumeta
