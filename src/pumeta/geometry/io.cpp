#include "pumeta/geometry/io.h"

#include <ATen/ATen.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "pumeta/core/error.h"
#include "pumeta/core/tensor_checks.h"
#include "pumeta/geometry/io/file.h"
#include "pumeta/geometry/io/formats.h"

namespace pumeta {

namespace {

using Reader = Geometry (*)(const std::string& path, std::string_view data);
using Writer = std::string (*)(const Geometry& geometry, bool binary);

struct Format {
    const char* name;
    std::vector<const char*> extensions;
    Reader read;
    Writer write;  // nullptr for read-only formats
    bool holds_faces;
    bool is_text;      // entirely text, so a UTF-16 byte order mark cannot be binary data
    bool starts_text;  // begins with a text line, so a UTF-8 byte order mark is not data
};

// The one place that knows which formats exist.
const std::vector<Format>& format_table() {
    static const std::vector<Format> table = {
        {"ply", {"ply"}, io::read_ply, io::write_ply, true, false, true},
        {"xyz", {"xyz", "txt", "pts"}, io::read_xyz, io::write_xyz, false, true, true},
        {"off", {"off"}, io::read_off, io::write_off, true, true, true},
        {"obj", {"obj"}, io::read_obj, io::write_obj, true, true, true},
        {"stl", {"stl"}, io::read_stl, nullptr, true, false, false},
        {"pcd", {"pcd"}, io::read_pcd, io::write_pcd, false, false, true},
        {"las", {"las"}, io::read_las, nullptr, false, false, false},
    };
    return table;
}

std::string lower(std::string text) {
    std::transform(text.begin(), text.end(), text.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return text;
}

std::string join(const std::vector<std::string>& items, const char* prefix) {
    std::string text;
    for (const std::string& item : items) text += (text.empty() ? "" : ", ") + (prefix + item);
    return text;
}

std::string supported_extensions() {
    std::vector<std::string> extensions;
    for (const Format& format : format_table())
        extensions.insert(extensions.end(), format.extensions.begin(), format.extensions.end());
    return join(extensions, ".");
}

const Format& format_named(const std::string& name, const std::string& path) {
    const std::string key = lower(name);
    if (key == "laz") throw_input_error(path, "{}", io::kLazUnsupported);
    for (const Format& format : format_table())
        if (key == format.name) return format;
    throw_input_error(path, "unknown format '{}'; supported formats: {}", name,
                      join(readable_formats(), ""));
}

const Format& resolve_format(const std::string& path, const std::string& requested) {
    return format_named(requested.empty() ? format_from_path(path) : requested, path);
}

// Vertices with a NaN or infinite coordinate poison every later distance; they are an error
// unless the caller asked to drop them, which a mesh cannot do without breaking its faces.
void handle_non_finite(Geometry& geometry, const std::string& path, bool drop) {
    const at::Tensor& points = geometry.cloud.points;
    const float* p = points.data_ptr<float>();
    const int64_t n = points.size(0);
    int64_t bad = 0, first = -1;
    for (int64_t i = 0; i < n; ++i) {
        if (std::isfinite(p[3 * i]) && std::isfinite(p[3 * i + 1]) && std::isfinite(p[3 * i + 2]))
            continue;
        if (bad++ == 0) first = i;
    }
    if (bad == 0) return;
    if (!drop)
        throw_input_error(path,
                          "{} of {} points have NaN or infinite coordinates (the first is point "
                          "{}); set drop_invalid to drop them",
                          bad, n, first);
    if (geometry.is_mesh())
        throw_input_error(path,
                          "{} vertices have NaN or infinite coordinates (the first is vertex {}); "
                          "they cannot be dropped from a mesh, whose faces would dangle",
                          bad, first);
    const at::Tensor keep = at::isfinite(points).all(1).nonzero().squeeze(1);
    PointCloud& cloud = geometry.cloud;
    cloud.points = cloud.points.index_select(0, keep);
    if (cloud.has_normals()) cloud.normals = cloud.normals.index_select(0, keep);
    if (cloud.has_colors()) cloud.colors = cloud.colors.index_select(0, keep);
    spdlog::warn("{}: dropped {} of {} points with NaN or infinite coordinates", path, bad, n);
    if (cloud.size() == 0) throw_input_error(path, "no point has finite coordinates");
}

Geometry parse_checked(const std::string& path, std::string_view data, const ReadOptions& options,
                       bool keep_faces) {
    const Format& format = resolve_format(path, options.format);
    if (data.empty()) throw_input_error(path, "file is empty");
    const bool utf16_bom = data.size() >= 2 && ((data[0] == '\xFE' && data[1] == '\xFF') ||
                                                (data[0] == '\xFF' && data[1] == '\xFE'));
    if (utf16_bom && format.is_text)
        throw_input_error(path, "UTF-16 text is not supported; save the file as UTF-8 or ASCII");
    // A UTF-8 byte order mark (Windows editors write one) is not part of the text. Binary STL
    // and LAS are excluded: their first bytes are data.
    std::string_view text = data;
    if (format.starts_text && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    if (text.empty()) throw_input_error(path, "the file holds only a byte order mark");
    Geometry geometry = format.read(path, text);
    if (!keep_faces || (geometry.faces.defined() && geometry.faces.size(0) == 0))
        geometry.faces = at::Tensor();
    if (geometry.cloud.size() == 0) throw_input_error(path, "the file contains no points");
    handle_non_finite(geometry, path, options.drop_invalid);
    return geometry;
}

Geometry read_checked(const std::string& path, const ReadOptions& options, bool keep_faces) {
    resolve_format(path, options.format);  // an unknown format fails before any read
    return parse_checked(path, io::read_whole_file(path), options, keep_faces);
}

void check_attribute(const at::Tensor& tensor, int64_t n, at::ScalarType type, const char* what,
                     const std::string& path) {
    if (tensor.dim() != 2 || tensor.size(0) != n || tensor.size(1) != 3 ||
        tensor.scalar_type() != type)
        throw_input_error(path, "expected {} of shape [{}, 3] and type {}, found {} {}", what, n,
                          std::string(c10::toString(type)), shape_string(tensor),
                          std::string(c10::toString(tensor.scalar_type())));
}

at::Tensor cpu_contiguous(const at::Tensor& tensor) {
    return tensor.defined() ? tensor.to(at::kCPU).contiguous() : tensor;
}

void write_checked(const std::string& path, const Geometry& geometry, const WriteOptions& options) {
    const Format& format = resolve_format(path, options.format);
    if (!format.write)
        throw_input_error(path, "cannot write {} files; writable formats: {}", format.name,
                          join(writable_formats(), ""));
    const PointCloud& cloud = geometry.cloud;
    check_points(cloud.points, path);
    const int64_t n = cloud.points.size(0);
    if (cloud.has_normals()) check_attribute(cloud.normals, n, at::kFloat, "normals", path);
    if (cloud.has_colors()) check_attribute(cloud.colors, n, at::kByte, "colors", path);
    if (geometry.faces.defined()) {
        if (!format.holds_faces)
            throw_input_error(path,
                              "{} files cannot hold faces; write the mesh as .ply, .off or .obj",
                              format.name);
        check_faces(geometry.faces, n, path);
    }
    const Geometry prepared{
        {cpu_contiguous(cloud.points), cpu_contiguous(cloud.normals), cpu_contiguous(cloud.colors)},
        cpu_contiguous(geometry.faces)};
    io::write_atomically(path, format.write(prepared, options.binary));
}

}  // namespace

Geometry read_geometry(const std::string& path, const ReadOptions& options) {
    return read_checked(path, options, true);
}

Geometry parse_geometry(const std::string& name, std::string_view bytes,
                        const ReadOptions& options) {
    return parse_checked(name, bytes, options, true);
}

PointCloud read_point_cloud(const std::string& path, const ReadOptions& options) {
    return read_checked(path, options, false).cloud;
}

TriangleMesh read_mesh(const std::string& path, const ReadOptions& options) {
    Geometry geometry = read_checked(path, options, true);
    if (!geometry.is_mesh())
        throw_input_error(path, "the file has no faces, but a triangle mesh is needed");
    return geometry.mesh();
}

void write_point_cloud(const std::string& path, const PointCloud& cloud,
                       const WriteOptions& options) {
    write_checked(path, Geometry{cloud, at::Tensor()}, options);
}

void write_mesh(const std::string& path, const TriangleMesh& mesh, const WriteOptions& options) {
    if (!mesh.faces.defined()) throw_input_error(path, "the mesh has no faces tensor");
    write_checked(path, Geometry{{mesh.vertices, at::Tensor(), at::Tensor()}, mesh.faces}, options);
}

void write_geometry(const std::string& path, const Geometry& geometry,
                    const WriteOptions& options) {
    if (geometry.is_mesh()) {
        write_checked(path, geometry, options);
    } else {
        write_point_cloud(path, geometry.cloud, options);
    }
}

std::string format_from_path(const std::string& path) {
    std::string extension = lower(std::filesystem::path(path).extension().string());
    if (!extension.empty()) extension.erase(0, 1);
    if (extension == "laz") throw_input_error(path, "{}", io::kLazUnsupported);
    for (const Format& format : format_table())
        for (const char* candidate : format.extensions)
            if (extension == candidate) return format.name;
    if (extension.empty())
        throw_input_error(path, "no file extension to tell the format; supported: {}",
                          supported_extensions());
    throw_input_error(path, "unknown file extension '.{}'; supported: {}", extension,
                      supported_extensions());
}

const std::vector<std::string>& readable_formats() {
    static const std::vector<std::string> names = [] {
        std::vector<std::string> list;
        for (const Format& format : format_table()) list.push_back(format.name);
        return list;
    }();
    return names;
}

const std::vector<std::string>& writable_formats() {
    static const std::vector<std::string> names = [] {
        std::vector<std::string> list;
        for (const Format& format : format_table())
            if (format.write) list.push_back(format.name);
        return list;
    }();
    return names;
}

}  // namespace pumeta
