// Reading and writing point clouds and meshes; the format comes from the file extension
// unless ReadOptions::format / WriteOptions::format names one.
//
// Readers: .ply (ascii, binary little/big endian, any scalar type, extra properties ignored,
// polygons triangulated), .xyz/.txt/.pts (3 or 6 columns, optional count header line),
// .off (OFF/COFF/NOFF, comments, polygons), .obj (v/vn/f, negative indices), .stl (ascii and
// binary), .pcd (ascii and binary), .las (1.2-1.4 uncompressed, point formats 0-10 that carry
// xyz; scale/offset applied). .laz is rejected with a clear message.
// Writers: .ply (binary little endian by default, or ascii), .xyz, .pcd (binary or ascii),
// meshes additionally as .off and .obj.
//
// Every failure throws InputError with "<path>: <what is wrong>" (with a line number or byte
// offset where one applies). Writers write to a temporary file beside the target and rename it,
// so a failed write never leaves a partial output file.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta {

struct ReadOptions {
    /// Format name ("ply", "xyz", "off", "obj", "stl", "pcd", "las"); empty = by extension.
    std::string format;
    /// Non-finite coordinates are an error by default; when true, such vertices are dropped
    /// (a warning reports the count). Dropping is refused for meshes (faces would dangle).
    bool drop_invalid = false;
};

struct WriteOptions {
    /// Format name ("ply", "xyz", "pcd", "off", "obj"); empty = by extension.
    std::string format;
    /// Binary output where the format has one (PLY: binary little endian; PCD: binary).
    bool binary = true;
};

/// Reads any supported file. Meshes keep their faces; point formats leave faces undefined.
Geometry read_geometry(const std::string& path, const ReadOptions& options = {});

/// read_geometry on a file's bytes already in memory; `name` gives the format by its
/// extension (unless options.format is set) and names the input in messages.
Geometry parse_geometry(const std::string& name, std::string_view bytes,
                        const ReadOptions& options = {});

/// Reads the vertices of any supported file (a mesh's vertices count as points).
PointCloud read_point_cloud(const std::string& path, const ReadOptions& options = {});

/// Reads a triangle mesh; InputError if the file has no faces.
TriangleMesh read_mesh(const std::string& path, const ReadOptions& options = {});

/// Writes a cloud (with its normals and colours where the format can hold them).
void write_point_cloud(const std::string& path, const PointCloud& cloud,
                       const WriteOptions& options = {});

/// Writes a mesh as .ply, .off or .obj.
void write_mesh(const std::string& path, const TriangleMesh& mesh,
                const WriteOptions& options = {});

/// Writes a Geometry: as a mesh when it has faces, else as a cloud.
void write_geometry(const std::string& path, const Geometry& geometry,
                    const WriteOptions& options = {});

/// Lower-case format name for a path ("ply", ...) from its extension; InputError when unknown
/// (and for .laz, with a message saying that compressed LAS is not supported).
std::string format_from_path(const std::string& path);

/// Formats the readers and writers accept.
const std::vector<std::string>& readable_formats();
const std::vector<std::string>& writable_formats();

}  // namespace pumeta
