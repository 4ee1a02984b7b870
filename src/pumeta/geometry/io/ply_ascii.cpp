// The PLY body reader for ascii files: one row per line, values parsed with their declared type.
#include <ATen/ATen.h>
#include <fmt/format.h>

#include <optional>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/mesh_builder.h"
#include "pumeta/geometry/io/ply_format.h"
#include "pumeta/geometry/io/text.h"

namespace pumeta::io::ply {

namespace {

// Parses an ascii value with the precision of its declared type, so that a float written with
// its shortest representation reads back bit-exactly.
bool parse_value(std::string_view token, ScalarType type, double& value) {
    if (type == ScalarType::Float32) {
        float f;
        if (!parse_number(token, f)) return false;
        value = f;
        return true;
    }
    if (type == ScalarType::Float64) return parse_number(token, value);
    int64_t integer;
    if (!parse_number(token, integer)) return false;
    value = static_cast<double>(integer);
    return true;
}

class AsciiReader {
  public:
    AsciiReader(const std::string& path, std::string_view data, const Header& header)
        : path_(path),
          data_(data),
          header_(header),
          lines_(data, header.data_offset, header.header_lines) {}

    Geometry read() {
        const FaceSource faces = find_faces(path_, header_);
        std::optional<VertexSink> vertices;
        std::optional<VertexLayout> layout;
        std::optional<TriangleBuilder> triangles;
        int64_t vertex_count = 0;
        for (const Element& element : header_.elements)
            if (element.name == "vertex") {
                vertex_count = static_cast<int64_t>(element.count);
                break;
            }
        std::vector<int64_t> polygon;
        for (size_t e = 0; e < header_.elements.size(); ++e) {
            const Element& element = header_.elements[e];
            if (element.properties.empty()) continue;  // rows without values take no text
            check_declared_size(element);
            if (!vertices && element.name == "vertex") {
                layout = vertex_layout(path_, element);
                vertices.emplace(static_cast<int64_t>(element.count), *layout);
                read_rows(
                    element,
                    [&](uint64_t row, size_t p, std::string_view token) {
                        const int target = layout->target[p];
                        if (target < 0) return;
                        const ScalarType type = element.properties[p].type;
                        vertices->store(row, target, parse(token, type, "a number"), type);
                    },
                    [](uint64_t, size_t, size_t, const std::string_view*) {});
            } else if (static_cast<int>(e) == faces.element) {
                triangles.emplace(path_, vertex_count);
                const ScalarType type = element.properties[faces.property].type;
                read_rows(
                    element, [](uint64_t, size_t, std::string_view) {},
                    [&](uint64_t row, size_t p, size_t length, const std::string_view* items) {
                        if (static_cast<int>(p) != faces.property) return;
                        polygon.resize(length);
                        for (size_t i = 0; i < length; ++i)
                            polygon[i] =
                                static_cast<int64_t>(parse(items[i], type, "a vertex index"));
                        const int64_t line = lines_.line_number();
                        triangles->add_polygon(polygon.data(), length, [&] {
                            return fmt::format("line {} (face {})", line, row);
                        });
                    });
            } else {
                read_rows(
                    element, [](uint64_t, size_t, std::string_view) {},
                    [](uint64_t, size_t, size_t, const std::string_view*) {});
            }
        }
        if (!vertices) throw_input_error(path_, "the PLY file has no 'vertex' element");
        return {{vertices->points, vertices->normals, vertices->colors},
                triangles ? triangles->faces() : at::Tensor()};
    }

  private:
    // A row of k values takes at least 2k - 1 bytes (digits and separators), so a larger
    // count is a lie that must not reach the allocator. Smaller lies are reported with their
    // line number while reading.
    void check_declared_size(const Element& element) const {
        const uint64_t available = data_.size() - std::min(lines_.offset(), data_.size());
        const uint64_t row = 2 * element.properties.size() - 1;
        if (element.count > available / row)
            throw_input_error(path_,
                              "the header declares {} '{}' rows, more than the {} bytes left "
                              "after line {} can hold",
                              element.count, element.name, available, lines_.line_number());
    }

    double parse(std::string_view token, ScalarType type, const char* what) const {
        double value;
        if (!parse_value(token, type, value))
            throw_input_error(path_, "line {}: expected {}, found '{}'", lines_.line_number(), what,
                              printable(token));
        return value;
    }

    // One row per line: on_scalar(row, property, token), on_list(row, property, length, items).
    template <typename OnScalar, typename OnList>
    void read_rows(const Element& element, OnScalar on_scalar, OnList on_list) {
        std::string_view line;
        for (uint64_t row = 0; row < element.count; ++row) {
            if (!lines_.next_content(line))
                throw_input_error(path_,
                                  "line {}: the file ends after {} of the {} '{}' rows that the "
                                  "header declares",
                                  lines_.line_number(), row, element.count, element.name);
            split_tokens(line, tokens_);
            size_t t = 0;
            for (size_t p = 0; p < element.properties.size(); ++p) {
                const Property& property = element.properties[p];
                if (t >= tokens_.size()) fail_missing(element, property);
                if (!property.is_list) {
                    on_scalar(row, p, tokens_[t++]);
                    continue;
                }
                int64_t length = -1;
                if (!parse_number(tokens_[t], length) || length < 0)
                    throw_input_error(path_, "line {}: expected a list length, found '{}'",
                                      lines_.line_number(), printable(tokens_[t]));
                ++t;
                if (static_cast<uint64_t>(length) > tokens_.size() - t)
                    throw_input_error(path_, "line {}: list '{}' declares {} items, found {}",
                                      lines_.line_number(), property.name, length,
                                      tokens_.size() - t);
                on_list(row, p, static_cast<size_t>(length), tokens_.data() + t);
                t += length;
            }
        }
    }

    [[noreturn]] void fail_missing(const Element& element, const Property& property) const {
        throw_input_error(path_, "line {}: '{}' row has no value for property '{}'",
                          lines_.line_number(), element.name, property.name);
    }

    const std::string& path_;
    std::string_view data_;
    const Header& header_;
    LineReader lines_;
    std::vector<std::string_view> tokens_;
};

}  // namespace

Geometry read_ascii(const std::string& path, std::string_view data, const Header& header) {
    return AsciiReader(path, data, header).read();
}

}  // namespace pumeta::io::ply
