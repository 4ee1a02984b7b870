#include "pumeta/geometry/io/mesh_builder.h"

#include <ATen/ATen.h>

#include <cstring>

#include "pumeta/core/error.h"

namespace pumeta::io {

namespace {

template <typename T>
at::Tensor copy_rows(const std::vector<T>& values, at::ScalarType type) {
    at::Tensor tensor = at::empty({static_cast<int64_t>(values.size() / 3), 3}, type);
    if (!values.empty()) std::memcpy(tensor.data_ptr(), values.data(), values.size() * sizeof(T));
    return tensor;
}

}  // namespace

at::Tensor TriangleBuilder::faces() const { return copy_rows(indices_, at::kLong); }

void TriangleBuilder::fail_too_few(const std::string& where, size_t count) const {
    throw_input_error(path_, "{}: a polygon needs at least 3 vertices, found {}", where, count);
}

void TriangleBuilder::fail_out_of_range(const std::string& where, int64_t index) const {
    throw_input_error(path_, "{}: vertex index {} out of range (the file has {} vertices)", where,
                      index, num_vertices_);
}

at::Tensor rows_tensor(const std::vector<float>& values) { return copy_rows(values, at::kFloat); }

at::Tensor rows_tensor(const std::vector<uint8_t>& values) { return copy_rows(values, at::kByte); }

}  // namespace pumeta::io
