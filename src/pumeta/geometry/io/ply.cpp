// PLY (Stanford polygon file format): ascii, binary little endian and binary big endian.
// Vertices carry x,y,z, optionally nx,ny,nz and red,green,blue; faces come from the
// `vertex_indices` (or `vertex_index`) list of the "face" element; every other element and
// property is skipped.
#include <ATen/ATen.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>
#include <optional>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/binary.h"
#include "pumeta/geometry/io/formats.h"
#include "pumeta/geometry/io/mesh_builder.h"
#include "pumeta/geometry/io/text.h"

namespace pumeta::io {

namespace {

enum class ScalarType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

struct TypeName {
    const char* name;
    ScalarType type;
};

constexpr TypeName kTypeNames[] = {
    {"char", ScalarType::Int8},      {"int8", ScalarType::Int8},
    {"uchar", ScalarType::UInt8},    {"uint8", ScalarType::UInt8},
    {"short", ScalarType::Int16},    {"int16", ScalarType::Int16},
    {"ushort", ScalarType::UInt16},  {"uint16", ScalarType::UInt16},
    {"int", ScalarType::Int32},      {"int32", ScalarType::Int32},
    {"uint", ScalarType::UInt32},    {"uint32", ScalarType::UInt32},
    {"float", ScalarType::Float32},  {"float32", ScalarType::Float32},
    {"double", ScalarType::Float64}, {"float64", ScalarType::Float64},
};

size_t type_size(ScalarType type) {
    switch (type) {
        case ScalarType::Int8:
        case ScalarType::UInt8:
            return 1;
        case ScalarType::Int16:
        case ScalarType::UInt16:
            return 2;
        case ScalarType::Int32:
        case ScalarType::UInt32:
        case ScalarType::Float32:
            return 4;
        case ScalarType::Float64:
            return 8;
    }
    return 0;
}

bool is_float(ScalarType type) {
    return type == ScalarType::Float32 || type == ScalarType::Float64;
}

double load_value(const char* bytes, ScalarType type, bool swap) {
    switch (type) {
        case ScalarType::Int8:
            return load<int8_t>(bytes);
        case ScalarType::UInt8:
            return load<uint8_t>(bytes);
        case ScalarType::Int16:
            return load<int16_t>(bytes, swap);
        case ScalarType::UInt16:
            return load<uint16_t>(bytes, swap);
        case ScalarType::Int32:
            return load<int32_t>(bytes, swap);
        case ScalarType::UInt32:
            return load<uint32_t>(bytes, swap);
        case ScalarType::Float32:
            return load<float>(bytes, swap);
        case ScalarType::Float64:
            return load<double>(bytes, swap);
    }
    return 0;
}

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

// Integer colours are clamped to 0..255; floating-point colours are taken as 0..1.
uint8_t to_color(double value, ScalarType type) {
    if (is_float(type)) value = std::round(value * 255.0);
    if (!(value >= 0)) return 0;  // also NaN
    return static_cast<uint8_t>(std::min(value, 255.0));
}

enum class Encoding { Ascii, BinaryLittleEndian, BinaryBigEndian };

struct Property {
    std::string name;
    ScalarType type;  // the value type; for a list, the item type
    bool is_list = false;
    ScalarType count_type = ScalarType::UInt8;
};

struct Element {
    std::string name;
    uint64_t count = 0;
    std::vector<Property> properties;

    bool has_lists() const {
        return std::any_of(properties.begin(), properties.end(),
                           [](const Property& p) { return p.is_list; });
    }
    // Bytes of one binary row: exact without lists, a lower bound with them (empty lists).
    size_t min_row_bytes() const {
        size_t bytes = 0;
        for (const Property& p : properties) bytes += type_size(p.is_list ? p.count_type : p.type);
        return bytes;
    }
    int find_scalar(std::initializer_list<const char*> names) const {
        for (size_t i = 0; i < properties.size(); ++i)
            for (const char* name : names)
                if (!properties[i].is_list && properties[i].name == name)
                    return static_cast<int>(i);
        return -1;
    }
    int find_list(std::initializer_list<const char*> names) const {
        for (size_t i = 0; i < properties.size(); ++i)
            for (const char* name : names)
                if (properties[i].is_list && properties[i].name == name) return static_cast<int>(i);
        return -1;
    }
};

struct Header {
    Encoding encoding = Encoding::Ascii;
    std::vector<Element> elements;
    size_t data_offset = 0;    // first byte after the end_header line
    int64_t header_lines = 0;  // lines up to and including end_header
};

ScalarType parse_type(std::string_view name, const std::string& path, int64_t line) {
    for (const TypeName& entry : kTypeNames)
        if (name == entry.name) return entry.type;
    throw_input_error(path, "line {}: unknown PLY property type '{}'", line, printable(name));
}

Header parse_header(const std::string& path, std::string_view data) {
    LineReader lines(data);
    std::string_view line;
    if (!lines.next(line) || trim(line) != "ply")
        throw_input_error(path, "not a PLY file (the first line is not 'ply')");
    Header header;
    bool have_format = false;
    std::vector<std::string_view> tokens;
    while (lines.next(line)) {
        const int64_t number = lines.line_number();
        split_tokens(line, tokens);
        if (tokens.empty()) continue;
        const std::string_view keyword = tokens[0];
        if (keyword == "end_header") {
            if (!have_format) throw_input_error(path, "PLY header has no 'format' line");
            header.data_offset = lines.offset();
            header.header_lines = number;
            return header;
        }
        if (keyword == "format") {
            if (tokens.size() < 2)
                throw_input_error(path, "line {}: 'format' without a value", number);
            if (tokens[1] == "ascii") {
                header.encoding = Encoding::Ascii;
            } else if (tokens[1] == "binary_little_endian") {
                header.encoding = Encoding::BinaryLittleEndian;
            } else if (tokens[1] == "binary_big_endian") {
                header.encoding = Encoding::BinaryBigEndian;
            } else {
                throw_input_error(path, "line {}: unknown PLY format '{}'", number,
                                  printable(tokens[1]));
            }
            have_format = true;
        } else if (keyword == "element") {
            int64_t count = -1;
            if (tokens.size() != 3 || !parse_number(tokens[2], count) || count < 0)
                throw_input_error(path, "line {}: expected 'element <name> <count>', found '{}'",
                                  number, printable(line));
            header.elements.push_back({std::string(tokens[1]), static_cast<uint64_t>(count), {}});
        } else if (keyword == "property") {
            if (header.elements.empty())
                throw_input_error(path, "line {}: property before any element", number);
            Property property;
            if (tokens.size() == 5 && tokens[1] == "list") {
                property.is_list = true;
                property.count_type = parse_type(tokens[2], path, number);
                property.type = parse_type(tokens[3], path, number);
                property.name = tokens[4];
                if (is_float(property.count_type))
                    throw_input_error(path, "line {}: list count type must be an integer type",
                                      number);
            } else if (tokens.size() == 3) {
                property.type = parse_type(tokens[1], path, number);
                property.name = tokens[2];
            } else {
                throw_input_error(path, "line {}: malformed property line '{}'", number,
                                  printable(line));
            }
            header.elements.back().properties.push_back(property);
        }
        // Other lines are skipped like comments: old exporters (Blender 2.4) wrote free text
        // without the "comment" keyword.
    }
    throw_input_error(path, "PLY header has no 'end_header' line");
}

// Where each vertex property goes: 0-2 point, 3-5 normal, 6-8 colour, -1 nowhere.
struct VertexLayout {
    std::vector<int> target;
    bool has_normals = false;
    bool has_colors = false;
};

VertexLayout vertex_layout(const std::string& path, const Element& vertex) {
    const int xyz[3] = {vertex.find_scalar({"x"}), vertex.find_scalar({"y"}),
                        vertex.find_scalar({"z"})};
    const int normal[3] = {vertex.find_scalar({"nx"}), vertex.find_scalar({"ny"}),
                           vertex.find_scalar({"nz"})};
    const int color[3] = {vertex.find_scalar({"red", "diffuse_red"}),
                          vertex.find_scalar({"green", "diffuse_green"}),
                          vertex.find_scalar({"blue", "diffuse_blue"})};
    if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
        throw_input_error(path, "the 'vertex' element lacks an x, y or z property");
    VertexLayout layout;
    layout.target.assign(vertex.properties.size(), -1);
    layout.has_normals = normal[0] >= 0 && normal[1] >= 0 && normal[2] >= 0;
    layout.has_colors = color[0] >= 0 && color[1] >= 0 && color[2] >= 0;
    for (int axis = 0; axis < 3; ++axis) {
        layout.target[xyz[axis]] = axis;
        if (layout.has_normals) layout.target[normal[axis]] = 3 + axis;
        if (layout.has_colors) layout.target[color[axis]] = 6 + axis;
    }
    return layout;
}

// The tensors being filled and how to store one parsed value into them.
struct VertexSink {
    at::Tensor points, normals, colors;
    float* point_data = nullptr;
    float* normal_data = nullptr;
    uint8_t* color_data = nullptr;

    VertexSink(int64_t count, const VertexLayout& layout) {
        points = at::empty({count, 3}, at::kFloat);
        point_data = points.data_ptr<float>();
        if (layout.has_normals) {
            normals = at::empty({count, 3}, at::kFloat);
            normal_data = normals.data_ptr<float>();
        }
        if (layout.has_colors) {
            colors = at::empty({count, 3}, at::kByte);
            color_data = colors.data_ptr<uint8_t>();
        }
    }

    void store(uint64_t row, int target, double value, ScalarType type) {
        if (target < 3) {
            point_data[3 * row + target] = static_cast<float>(value);
        } else if (target < 6) {
            normal_data[3 * row + target - 3] = static_cast<float>(value);
        } else {
            color_data[3 * row + target - 6] = to_color(value, type);
        }
    }
};

struct FaceSource {
    int element = -1;   // index of the face element, -1 when the file has none
    int property = -1;  // its vertex index list
};

FaceSource find_faces(const std::string& path, const Header& header) {
    for (size_t e = 0; e < header.elements.size(); ++e) {
        const Element& element = header.elements[e];
        if (element.name != "face") continue;
        const int list = element.find_list({"vertex_indices", "vertex_index"});
        if (list < 0) continue;
        if (is_float(element.properties[list].type))
            throw_input_error(path, "face property '{}' has a floating-point index type",
                              element.properties[list].name);
        return {static_cast<int>(e), list};
    }
    return {};
}

class BinaryReader {
  public:
    BinaryReader(const std::string& path, std::string_view data, const Header& header)
        : path_(path),
          data_(data),
          header_(header),
          swap_(header.encoding == Encoding::BinaryBigEndian),
          position_(header.data_offset) {}

    Geometry read() {
        check_declared_sizes();
        const FaceSource faces = find_faces(path_, header_);
        std::optional<VertexSink> vertices;
        std::optional<TriangleBuilder> triangles;
        for (size_t e = 0; e < header_.elements.size(); ++e) {
            const Element& element = header_.elements[e];
            if (!vertices && element.name == "vertex") {
                VertexLayout layout = vertex_layout(path_, element);
                vertices.emplace(static_cast<int64_t>(element.count), layout);
                read_vertices(element, layout, *vertices);
            } else if (static_cast<int>(e) == faces.element) {
                triangles.emplace(path_, vertex_count());
                read_faces(element, faces.property, *triangles);
            } else {
                skip(element);
            }
        }
        if (!vertices) throw_input_error(path_, "the PLY file has no 'vertex' element");
        return {{vertices->points, vertices->normals, vertices->colors},
                triangles ? triangles->faces() : at::Tensor()};
    }

  private:
    int64_t vertex_count() const {
        for (const Element& element : header_.elements)
            if (element.name == "vertex") return static_cast<int64_t>(element.count);
        return 0;
    }

    size_t remaining() const { return data_.size() - position_; }

    // A header declaring more data than the file holds is rejected before any allocation.
    void check_declared_sizes() const {
        size_t offset = position_;
        for (const Element& element : header_.elements) {
            const size_t row = element.min_row_bytes();
            uint64_t needed = 0;
            const bool overflow = __builtin_mul_overflow(element.count, row, &needed);
            if (overflow || needed > data_.size() - offset)
                throw_input_error(
                    path_,
                    "truncated binary PLY: element '{}' declares {} rows of {}{} bytes "
                    "({}{} bytes) from byte offset {}, but only {} bytes remain",
                    element.name, element.count, element.has_lists() ? "at least " : "", row,
                    element.has_lists() ? "at least " : "",
                    overflow ? std::string("over 2^64") : std::to_string(needed), offset,
                    data_.size() - offset);
            offset += needed;
        }
    }

    [[noreturn]] void fail_truncated(const Element& element, uint64_t row, size_t needed) const {
        throw_input_error(path_,
                          "truncated binary PLY: element '{}' row {} needs {} bytes at byte "
                          "offset {}, found {}",
                          element.name, row, needed, position_, remaining());
    }

    void require(const Element& element, uint64_t row, size_t needed) const {
        if (needed > remaining()) fail_truncated(element, row, needed);
    }

    // The bytes of a list-free element's `count` rows at the current position, checked against
    // what remains: lists in earlier elements move the position past the up-front estimate.
    size_t fixed_block_bytes(const Element& element) const {
        uint64_t bytes = 0;
        if (__builtin_mul_overflow(element.count, element.min_row_bytes(), &bytes) ||
            bytes > remaining())
            throw_input_error(path_,
                              "truncated binary PLY: element '{}' needs {} rows of {} bytes "
                              "from byte offset {}, but only {} bytes remain",
                              element.name, element.count, element.min_row_bytes(), position_,
                              remaining());
        return static_cast<size_t>(bytes);
    }

    // Visits every value of a row-by-row walk: on_scalar(row, property, bytes) and
    // on_list(row, property, length, item_bytes).
    template <typename OnScalar, typename OnList>
    void walk(const Element& element, OnScalar on_scalar, OnList on_list) {
        for (uint64_t row = 0; row < element.count; ++row) {
            for (size_t p = 0; p < element.properties.size(); ++p) {
                const Property& property = element.properties[p];
                if (!property.is_list) {
                    const size_t size = type_size(property.type);
                    require(element, row, size);
                    on_scalar(row, p, data_.data() + position_);
                    position_ += size;
                    continue;
                }
                const size_t count_size = type_size(property.count_type);
                require(element, row, count_size);
                const double length =
                    load_value(data_.data() + position_, property.count_type, swap_);
                if (length < 0)
                    throw_input_error(path_,
                                      "element '{}' row {}: negative list length {} at byte "
                                      "offset {}",
                                      element.name, row, length, position_);
                position_ += count_size;
                const size_t item_size = type_size(property.type);
                const uint64_t items = static_cast<uint64_t>(length);
                if (items > remaining() / item_size)
                    fail_truncated(element, row, items * item_size);
                on_list(row, p, items, data_.data() + position_);
                position_ += items * item_size;
            }
        }
    }

    void read_vertices(const Element& element, const VertexLayout& layout, VertexSink& sink) {
        if (element.has_lists()) {
            walk(
                element,
                [&](uint64_t row, size_t p, const char* bytes) {
                    if (layout.target[p] < 0) return;
                    const ScalarType type = element.properties[p].type;
                    sink.store(row, layout.target[p], load_value(bytes, type, swap_), type);
                },
                [](uint64_t, size_t, uint64_t, const char*) {});
            return;
        }
        // Fixed layout (the common case): every value sits at a known offset of its row.
        const size_t block = fixed_block_bytes(element);
        if (element.count == 0) return;
        const size_t stride = element.min_row_bytes();
        const char* base = data_.data() + position_;
        const int64_t count = static_cast<int64_t>(element.count);
        std::vector<size_t> offsets(element.properties.size());
        for (size_t p = 1; p < offsets.size(); ++p)
            offsets[p] = offsets[p - 1] + type_size(element.properties[p - 1].type);
        copy_triple(base, stride, count, element, layout, offsets, 0, sink.point_data);
        if (sink.normal_data)
            copy_triple(base, stride, count, element, layout, offsets, 3, sink.normal_data);
        if (sink.color_data) {
            for (size_t p = 0; p < offsets.size(); ++p) {
                const int target = layout.target[p];
                if (target < 6) continue;
                const ScalarType type = element.properties[p].type;
                const char* value = base + offsets[p];
                if (type == ScalarType::UInt8) {
                    uint8_t* out = sink.color_data + (target - 6);
                    for (int64_t row = 0; row < count; ++row) out[3 * row] = value[row * stride];
                    continue;
                }
                for (int64_t row = 0; row < count; ++row)
                    sink.store(row, target, load_value(value + row * stride, type, swap_), type);
            }
        }
        position_ += block;
    }

    // Fills the float32 [count,3] `out` with the properties targeted first..first+2; three
    // adjacent little-endian floats are copied with one memcpy per row (or one in all).
    void copy_triple(const char* base, size_t stride, int64_t count, const Element& element,
                     const VertexLayout& layout, const std::vector<size_t>& offsets, int first,
                     float* out) const {
        int property[3];
        for (size_t p = 0; p < offsets.size(); ++p)
            if (layout.target[p] >= first && layout.target[p] < first + 3)
                property[layout.target[p] - first] = static_cast<int>(p);
        bool packed = !swap_;
        for (int axis = 0; axis < 3; ++axis)
            packed = packed && element.properties[property[axis]].type == ScalarType::Float32 &&
                     offsets[property[axis]] == offsets[property[0]] + 4 * axis;
        const size_t start = offsets[property[0]];
        if (packed && stride == 3 * sizeof(float)) {
            std::memcpy(out, base, count * stride);
        } else if (packed) {
            for (int64_t row = 0; row < count; ++row)
                std::memcpy(out + 3 * row, base + row * stride + start, 3 * sizeof(float));
        } else {
            for (int axis = 0; axis < 3; ++axis) {
                const ScalarType type = element.properties[property[axis]].type;
                const size_t offset = offsets[property[axis]];
                for (int64_t row = 0; row < count; ++row)
                    out[3 * row + axis] =
                        static_cast<float>(load_value(base + row * stride + offset, type, swap_));
            }
        }
    }

    void read_faces(const Element& element, size_t index_property, TriangleBuilder& triangles) {
        std::vector<int64_t> polygon;
        const ScalarType type = element.properties[index_property].type;
        walk(
            element, [](uint64_t, size_t, const char*) {},
            [&](uint64_t row, size_t p, uint64_t length, const char* items) {
                if (p != index_property) return;
                polygon.resize(length);
                for (uint64_t i = 0; i < length; ++i)
                    polygon[i] =
                        static_cast<int64_t>(load_value(items + i * type_size(type), type, swap_));
                triangles.add_polygon(polygon.data(), polygon.size(),
                                      [&] { return fmt::format("face {}", row); });
            });
    }

    void skip(const Element& element) {
        if (!element.has_lists()) {
            position_ += fixed_block_bytes(element);
            return;
        }
        walk(
            element, [](uint64_t, size_t, const char*) {},
            [](uint64_t, size_t, uint64_t, const char*) {});
    }

    const std::string& path_;
    std::string_view data_;
    const Header& header_;
    bool swap_;
    size_t position_;
};

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

Geometry read_ply(const std::string& path, std::string_view data) {
    const Header header = parse_header(path, data);
    if (header.encoding == Encoding::Ascii) return AsciiReader(path, data, header).read();
    return BinaryReader(path, data, header).read();
}

std::string write_ply(const Geometry& geometry, bool binary) {
    const PointCloud& cloud = geometry.cloud;
    const int64_t n = cloud.size();
    const int64_t f = geometry.faces.defined() ? geometry.faces.size(0) : 0;
    const float* points = cloud.points.data_ptr<float>();
    const float* normals = cloud.has_normals() ? cloud.normals.data_ptr<float>() : nullptr;
    const uint8_t* colors = cloud.has_colors() ? cloud.colors.data_ptr<uint8_t>() : nullptr;
    const int64_t* faces = f ? geometry.faces.data_ptr<int64_t>() : nullptr;

    std::string out = "ply\n";
    out += binary ? "format binary_little_endian 1.0\n" : "format ascii 1.0\n";
    out += "comment written by pumeta\n";
    fmt::format_to(std::back_inserter(out), "element vertex {}\n", n);
    out += "property float x\nproperty float y\nproperty float z\n";
    if (normals) out += "property float nx\nproperty float ny\nproperty float nz\n";
    if (colors) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    if (geometry.faces.defined())
        fmt::format_to(std::back_inserter(out),
                       "element face {}\nproperty list uchar int vertex_indices\n", f);
    out += "end_header\n";

    if (!binary) {
        for (int64_t i = 0; i < n; ++i) {
            const float* p = points + 3 * i;
            fmt::format_to(std::back_inserter(out), "{} {} {}", p[0], p[1], p[2]);
            if (normals) {
                const float* q = normals + 3 * i;
                fmt::format_to(std::back_inserter(out), " {} {} {}", q[0], q[1], q[2]);
            }
            if (colors) {
                const uint8_t* c = colors + 3 * i;
                fmt::format_to(std::back_inserter(out), " {} {} {}", c[0], c[1], c[2]);
            }
            out += '\n';
        }
        for (int64_t i = 0; i < f; ++i) {
            const int64_t* t = faces + 3 * i;
            fmt::format_to(std::back_inserter(out), "3 {} {} {}\n", t[0], t[1], t[2]);
        }
        return out;
    }

    const size_t row = 12 + (normals ? 12 : 0) + (colors ? 3 : 0);
    const size_t header_size = out.size();
    out.resize(header_size + row * n + 13 * f);
    char* cursor = out.data() + header_size;
    if (row == 12) {
        std::memcpy(cursor, points, 12 * n);
        cursor += 12 * n;
    } else {
        for (int64_t i = 0; i < n; ++i) {
            std::memcpy(cursor, points + 3 * i, 12);
            cursor += 12;
            if (normals) {
                std::memcpy(cursor, normals + 3 * i, 12);
                cursor += 12;
            }
            if (colors) {
                std::memcpy(cursor, colors + 3 * i, 3);
                cursor += 3;
            }
        }
    }
    for (int64_t i = 0; i < f; ++i) {
        *cursor++ = 3;
        for (int k = 0; k < 3; ++k) {
            const int32_t index = static_cast<int32_t>(faces[3 * i + k]);
            std::memcpy(cursor, &index, 4);
            cursor += 4;
        }
    }
    return out;
}

}  // namespace pumeta::io
