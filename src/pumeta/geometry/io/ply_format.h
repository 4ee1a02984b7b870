// Internal to the PLY reader (ply*.cpp): the scalar types, the parsed header and the mapping
// of its elements onto a Geometry, shared by the header parser and the ascii and binary readers.
#pragma once

#include <ATen/ATen.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include "pumeta/geometry/io/binary.h"
#include "pumeta/geometry/point_cloud.h"

namespace pumeta::io::ply {

enum class ScalarType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

inline size_t type_size(ScalarType type) {
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

inline bool is_float(ScalarType type) {
    return type == ScalarType::Float32 || type == ScalarType::Float64;
}

inline double load_value(const char* bytes, ScalarType type, bool swap) {
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

// Integer colours are clamped to 0..255; floating-point colours are taken as 0..1.
inline uint8_t to_color(double value, ScalarType type) {
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

/// Parses the header up to and including its end_header line; throws InputError when malformed.
Header parse_header(const std::string& path, std::string_view data);

// Where each vertex property goes: 0-2 point, 3-5 normal, 6-8 colour, -1 nowhere.
struct VertexLayout {
    std::vector<int> target;
    bool has_normals = false;
    bool has_colors = false;
};

/// The targets of the vertex element's properties; throws InputError without x, y and z.
VertexLayout vertex_layout(const std::string& path, const Element& vertex);

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

/// The first "face" element with a vertex index list, or none.
FaceSource find_faces(const std::string& path, const Header& header);

/// The body readers, for the encodings their names give, starting after the header.
Geometry read_ascii(const std::string& path, std::string_view data, const Header& header);
Geometry read_binary(const std::string& path, std::string_view data, const Header& header);

}  // namespace pumeta::io::ply
