// The PLY writer: ascii or binary little endian, with normals, colours and faces when present.
#include <ATen/ATen.h>
#include <fmt/format.h>

#include <cstring>
#include <iterator>

#include "pumeta/geometry/io/formats.h"

namespace pumeta::io {

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
