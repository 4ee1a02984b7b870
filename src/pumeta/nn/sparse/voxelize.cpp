#include "pumeta/nn/sparse/voxelize.h"

#include <ATen/ATen.h>

#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"

namespace pumeta {

at::Tensor voxel_coordinates(const at::Tensor& points, double voxel_size) {
    check_batched_points(points, "voxelize");
    if (!(voxel_size > 0))
        throw_input_error("voxelize", "voxel size must be > 0, found {}", voxel_size);
    at::Tensor p = points.detach().to(at::kCPU, at::kDouble);
    if (!at::isfinite(p).all().item<bool>()) throw_input_error("voxelize", "points must be finite");
    const int64_t batch = p.size(0), count = p.size(1);
    at::Tensor grid = at::floor(p / voxel_size).to(at::kLong).view({batch * count, 3});
    at::Tensor column =
        at::arange(batch, at::kLong).unsqueeze(1).expand({batch, count}).reshape({-1, 1});
    return at::cat({column, grid}, 1);
}

CoordinateSetPtr unique_sites(const at::Tensor& coords) {
    if (!coords.defined() || coords.dim() != 2 || coords.size(1) != 4)
        throw_input_error("voxelize", "expected sites of shape [M,4], found {}",
                          shape_string(coords));
    at::Tensor wide = coords.to(at::kCPU, at::kLong).contiguous();
    const int64_t* c = wide.data_ptr<int64_t>();
    CoordinateHash seen(wide.size(0));
    std::vector<int64_t> first;
    for (int64_t i = 0; i < wide.size(0); ++i) {
        const int64_t* row = c + 4 * i;
        if (!packable(row[0], row[1], row[2], row[3]))
            throw_input_error("voxelize",
                              "voxel ({}, {}, {}) is outside [{}, {}]: voxel size too small for "
                              "the extent of the points",
                              row[1], row[2], row[3], kMinCoordinate, kMaxCoordinate);
        int64_t next = int64_t(first.size());
        if (seen.insert(pack_coordinate(row[0], row[1], row[2], row[3]), next) == next)
            first.push_back(i);
    }
    at::Tensor rows = at::empty({int64_t(first.size())}, at::kLong);
    std::copy(first.begin(), first.end(), rows.data_ptr<int64_t>());
    return CoordinateSet::create(wide.index_select(0, rows), 1);
}

CoordinateSetPtr voxelize(const at::Tensor& points, double voxel_size) {
    return unique_sites(voxel_coordinates(points, voxel_size));
}

at::Tensor voxel_centres(const at::Tensor& coords, double voxel_size) {
    if (!coords.defined() || coords.dim() != 2 || coords.size(1) != 4)
        throw_input_error("voxel centres", "expected sites of shape [M,4], found {}",
                          shape_string(coords));
    return ((coords.narrow(1, 1, 3).to(at::kDouble) + 0.5) * voxel_size).to(at::kFloat);
}

}  // namespace pumeta
