// Wavefront OBJ: "v x y z" vertices and "f" polygons whose corners are "v", "v/vt",
// "v//vn" or "v/vt/vn" with 1-based or negative (relative to the last vertex) indices.
// Other statements (vn, vt, g, o, s, usemtl, mtllib, l, p, ...) are ignored.
#include <ATen/ATen.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <iterator>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/formats.h"
#include "pumeta/geometry/io/mesh_builder.h"
#include "pumeta/geometry/io/text.h"

namespace pumeta::io {

Geometry read_obj(const std::string& path, std::string_view data) {
    LineReader lines(data);
    std::vector<std::string_view> tokens;
    std::vector<float> points;
    std::vector<int64_t> triangles;
    std::vector<int64_t> polygon;
    bool has_faces = false;
    int64_t skipped_edges = 0;
    std::string_view line;
    while (lines.next_content(line, '#')) {
        split_tokens(line, tokens);
        const int64_t number = lines.line_number();
        if (tokens[0] == "v") {
            if (tokens.size() < 4)
                throw_input_error(path, "line {}: a vertex needs 3 coordinates, found {}", number,
                                  tokens.size() - 1);
            for (int axis = 1; axis <= 3; ++axis)
                points.push_back(parse_or_throw<float>(tokens[axis], path, number, "a coordinate"));
        } else if (tokens[0] == "f") {
            if (tokens.size() < 3)
                throw_input_error(path, "line {}: a face needs at least 3 vertices, found {}",
                                  number, tokens.size() - 1);
            // Indices refer to the vertices defined so far; negative ones count back from the
            // last of them.
            const int64_t defined = static_cast<int64_t>(points.size() / 3);
            polygon.clear();
            for (size_t k = 1; k < tokens.size(); ++k) {
                const std::string_view corner = tokens[k].substr(0, tokens[k].find('/'));
                const int64_t index =
                    parse_or_throw<int64_t>(corner, path, number, "a vertex index");
                const int64_t resolved = index > 0 ? index - 1 : defined + index;
                if (index == 0 || resolved < 0 || resolved >= defined)
                    throw_input_error(path,
                                      "line {}: vertex index {} out of range ({} vertices defined "
                                      "so far; indices start at 1, negative ones count back)",
                                      number, index, defined);
                polygon.push_back(resolved);
            }
            // Two-vertex "faces" (edges written as faces by some exporters) hold no surface:
            // skipped, like other readers do, and reported once below.
            if (polygon.size() < 3) {
                ++skipped_edges;
                continue;
            }
            for (size_t k = 1; k + 1 < polygon.size(); ++k)
                triangles.insert(triangles.end(), {polygon[0], polygon[k], polygon[k + 1]});
            has_faces = true;
        }
    }
    if (skipped_edges > 0) spdlog::warn("{}: skipped {} two-vertex face(s)", path, skipped_edges);
    Geometry geometry;
    geometry.cloud.points = rows_tensor(points);
    if (has_faces) {
        geometry.faces = at::empty({static_cast<int64_t>(triangles.size() / 3), 3}, at::kLong);
        std::copy(triangles.begin(), triangles.end(), geometry.faces.data_ptr<int64_t>());
    }
    return geometry;
}

std::string write_obj(const Geometry& geometry, bool /*binary*/) {
    const float* points = geometry.cloud.points.data_ptr<float>();
    const int64_t n = geometry.cloud.size();
    const int64_t f = geometry.faces.defined() ? geometry.faces.size(0) : 0;
    std::string out = "# written by pumeta\n";
    for (int64_t i = 0; i < n; ++i)
        fmt::format_to(std::back_inserter(out), "v {} {} {}\n", points[3 * i], points[3 * i + 1],
                       points[3 * i + 2]);
    const int64_t* faces = f ? geometry.faces.data_ptr<int64_t>() : nullptr;
    for (int64_t i = 0; i < f; ++i)
        fmt::format_to(std::back_inserter(out), "f {} {} {}\n", faces[3 * i] + 1,
                       faces[3 * i + 1] + 1, faces[3 * i + 2] + 1);
    return out;
}

}  // namespace pumeta::io
