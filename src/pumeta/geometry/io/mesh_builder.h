// Building the tensors of a Geometry from values parsed one by one: polygons fan-triangulated
// with their indices checked, and flat value vectors turned into [N,3] tensors.
#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <string>
#include <vector>

namespace pumeta::io {

/// Collects polygons as triangles (v0, vi, vi+1), rejecting polygons with fewer than three
/// vertices and indices outside [0, num_vertices) with an InputError naming the polygon.
class TriangleBuilder {
  public:
    TriangleBuilder(const std::string& path, int64_t num_vertices)
        : path_(path), num_vertices_(num_vertices) {}

    /// `where()` returns the polygon's description for error messages ("line 12 (face 3)");
    /// it is only called on failure.
    template <typename Where>
    void add_polygon(const int64_t* indices, size_t count, const Where& where) {
        if (count < 3) fail_too_few(where(), count);
        for (size_t i = 0; i < count; ++i)
            if (indices[i] < 0 || indices[i] >= num_vertices_)
                fail_out_of_range(where(), indices[i]);
        for (size_t i = 1; i + 1 < count; ++i) {
            indices_.push_back(indices[0]);
            indices_.push_back(indices[i]);
            indices_.push_back(indices[i + 1]);
        }
    }

    /// int64 [F,3].
    at::Tensor faces() const;

  private:
    [[noreturn]] void fail_too_few(const std::string& where, size_t count) const;
    [[noreturn]] void fail_out_of_range(const std::string& where, int64_t index) const;

    std::string path_;
    int64_t num_vertices_;
    std::vector<int64_t> indices_;
};

/// float32 [N,3] holding `values` (3N floats, row-major).
at::Tensor rows_tensor(const std::vector<float>& values);

/// uint8 [N,3] holding `values` (3N bytes, row-major).
at::Tensor rows_tensor(const std::vector<uint8_t>& values);

}  // namespace pumeta::io
