// OFF (Object File Format): a header keyword ([ST][C][N]OFF), the counts "V F [E]", V vertex
// lines "x y z [nx ny nz] [colour] [s t]" and F polygon lines "n i1 .. in [colour]".
// '#' starts a comment; colour and texture columns are ignored; NOFF normals are kept.
#include <ATen/ATen.h>
#include <fmt/format.h>

#include <iterator>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/formats.h"
#include "pumeta/geometry/io/mesh_builder.h"
#include "pumeta/geometry/io/text.h"

namespace pumeta::io {

namespace {

// True for the OFF keywords this reader understands; sets whether vertices carry normals.
bool parse_keyword(std::string_view keyword, bool& has_normals) {
    if (keyword.size() >= 2 && keyword.substr(0, 2) == "ST") keyword.remove_prefix(2);
    if (!keyword.empty() && keyword[0] == 'C') keyword.remove_prefix(1);
    has_normals = !keyword.empty() && keyword[0] == 'N';
    if (has_normals) keyword.remove_prefix(1);
    return keyword == "OFF";
}

}  // namespace

Geometry read_off(const std::string& path, std::string_view data) {
    LineReader lines(data);
    std::vector<std::string_view> tokens;
    std::string_view line;
    if (!lines.next_content(line, '#')) throw_input_error(path, "the OFF file has no header");
    split_tokens(line, tokens);
    bool has_normals = false;
    if (!parse_keyword(tokens[0], has_normals))
        throw_input_error(path,
                          "line {}: expected an OFF header (OFF, COFF, NOFF, ...), found '{}'",
                          lines.line_number(), printable(tokens[0]));
    if (tokens.size() > 1 && tokens[1] == "BINARY")
        throw_input_error(path, "line {}: binary OFF is not supported", lines.line_number());
    // The counts may follow the keyword on the same line.
    tokens.erase(tokens.begin());
    if (tokens.empty()) {
        if (!lines.next_content(line, '#'))
            throw_input_error(path, "the file ends before the vertex and face counts");
        split_tokens(line, tokens);
    }
    const int64_t counts_line = lines.line_number();
    if (tokens.size() < 2 || tokens.size() > 3)
        throw_input_error(path, "line {}: expected 'vertices faces [edges]', found '{}'",
                          counts_line, printable(line));
    const int64_t num_vertices =
        parse_or_throw<int64_t>(tokens[0], path, counts_line, "a vertex count");
    const int64_t num_faces = parse_or_throw<int64_t>(tokens[1], path, counts_line, "a face count");
    // A vertex line takes at least 5 bytes ("0 0 0") and a face line at least one, so larger
    // counts are lies, rejected before they reach the allocator (smaller ones are reported
    // with their line number).
    const int64_t room = static_cast<int64_t>(data.size() - lines.offset());
    if (num_vertices < 0 || num_faces < 0 || num_vertices > room || num_faces > room ||
        5 * num_vertices + num_faces > room)
        throw_input_error(path,
                          "line {}: the header declares {} vertices and {} faces, which the {} "
                          "remaining bytes cannot hold",
                          counts_line, num_vertices, num_faces, data.size() - lines.offset());

    at::Tensor points = at::empty({num_vertices, 3}, at::kFloat);
    at::Tensor normals = has_normals ? at::empty({num_vertices, 3}, at::kFloat) : at::Tensor();
    float* p = points.data_ptr<float>();
    float* q = has_normals ? normals.data_ptr<float>() : nullptr;
    const size_t vertex_columns = has_normals ? 6 : 3;
    for (int64_t i = 0; i < num_vertices; ++i) {
        if (!lines.next_content(line, '#'))
            throw_input_error(path, "line {}: the file ends after {} of {} vertices",
                              lines.line_number(), i, num_vertices);
        split_tokens(line, tokens);
        const int64_t number = lines.line_number();
        if (tokens.size() < vertex_columns)
            throw_input_error(path, "line {}: expected {} values for a vertex, found {}", number,
                              vertex_columns, tokens.size());
        for (int axis = 0; axis < 3; ++axis)
            p[3 * i + axis] = parse_or_throw<float>(tokens[axis], path, number, "a coordinate");
        if (q)
            for (int axis = 0; axis < 3; ++axis)
                q[3 * i + axis] =
                    parse_or_throw<float>(tokens[3 + axis], path, number, "a normal component");
    }

    TriangleBuilder triangles(path, num_vertices);
    std::vector<int64_t> polygon;
    for (int64_t f = 0; f < num_faces; ++f) {
        if (!lines.next_content(line, '#'))
            throw_input_error(path, "line {}: the file ends after {} of {} faces",
                              lines.line_number(), f, num_faces);
        split_tokens(line, tokens);
        const int64_t number = lines.line_number();
        const int64_t size = parse_or_throw<int64_t>(tokens[0], path, number, "a polygon size");
        if (size < 0 || static_cast<uint64_t>(size) > tokens.size() - 1)
            throw_input_error(path, "line {}: the polygon declares {} vertices, found {} indices",
                              number, size, tokens.size() - 1);
        polygon.resize(size);
        for (int64_t k = 0; k < size; ++k)
            polygon[k] = parse_or_throw<int64_t>(tokens[1 + k], path, number, "a vertex index");
        triangles.add_polygon(polygon.data(), polygon.size(),
                              [&] { return fmt::format("line {} (face {})", number, f); });
    }
    return {{points, normals, at::Tensor()}, triangles.faces()};
}

std::string write_off(const Geometry& geometry, bool /*binary*/) {
    const float* points = geometry.cloud.points.data_ptr<float>();
    const int64_t n = geometry.cloud.size();
    const int64_t f = geometry.faces.defined() ? geometry.faces.size(0) : 0;
    std::string out;
    fmt::format_to(std::back_inserter(out), "OFF\n{} {} 0\n", n, f);
    for (int64_t i = 0; i < n; ++i)
        fmt::format_to(std::back_inserter(out), "{} {} {}\n", points[3 * i], points[3 * i + 1],
                       points[3 * i + 2]);
    const int64_t* faces = f ? geometry.faces.data_ptr<int64_t>() : nullptr;
    for (int64_t i = 0; i < f; ++i)
        fmt::format_to(std::back_inserter(out), "3 {} {} {}\n", faces[3 * i], faces[3 * i + 1],
                       faces[3 * i + 2]);
    return out;
}

}  // namespace pumeta::io
