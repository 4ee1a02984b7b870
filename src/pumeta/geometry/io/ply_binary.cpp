// The PLY body reader for binary little and big endian files, with the bounds checks that keep
// a header declaring more data than the file holds from reaching the allocator.
#include <ATen/ATen.h>
#include <fmt/format.h>

#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/mesh_builder.h"
#include "pumeta/geometry/io/ply_format.h"

namespace pumeta::io::ply {

namespace {

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

}  // namespace

Geometry read_binary(const std::string& path, std::string_view data, const Header& header) {
    return BinaryReader(path, data, header).read();
}

}  // namespace pumeta::io::ply
