#include "fuzz/contract.h"

#include <ATen/ATen.h>
#include <fmt/format.h>

#include "pumeta/geometry/io.h"

namespace pumeta::fuzz {

namespace {

void check_rows(const at::Tensor& tensor, int64_t n, at::ScalarType type, const char* what) {
    if (!tensor.defined()) return;
    if (tensor.dim() != 2 || tensor.size(0) != n || tensor.size(1) != 3 ||
        tensor.scalar_type() != type)
        violated(fmt::format("{} do not match the {} points", what, n));
}

}  // namespace

void read_geometry_contract(const std::string& name, std::string_view bytes) {
    const Geometry geometry = parse_geometry(name, bytes);
    const at::Tensor& points = geometry.cloud.points;
    if (points.dim() != 2 || points.size(1) != 3 || points.scalar_type() != at::kFloat)
        violated("points are not float32 [N,3]");
    const int64_t n = points.size(0);
    if (n == 0) violated("an empty cloud was returned");
    if (!at::isfinite(points).all().item<bool>()) violated("non-finite coordinates were returned");
    check_rows(geometry.cloud.normals, n, at::kFloat, "normals");
    check_rows(geometry.cloud.colors, n, at::kByte, "colours");
    if (geometry.faces.defined()) {
        const at::Tensor& faces = geometry.faces;
        if (faces.dim() != 2 || faces.size(1) != 3 || faces.scalar_type() != at::kLong)
            violated("faces are not int64 [F,3]");
        if (faces.numel() > 0 &&
            (faces.min().item<int64_t>() < 0 || faces.max().item<int64_t>() >= n))
            violated("a face index is out of range");
    }
}

}  // namespace pumeta::fuzz
