// The per-format readers and writers behind geometry/io.h, dispatched by its format table.
//
// Readers get the whole file in memory (`data`, never empty) and its path for messages. They
// return the vertices (float32 [N,3]) with normals and colours where the file carries them,
// and faces (int64 [F,3], indices already checked) for formats that hold faces. The caller
// checks for empty clouds and non-finite coordinates.
//
// Writers get contiguous CPU tensors already checked (points float32 [N,3], optional normals
// float32 [N,3] and colours uint8 [N,3], optional int64 [F,3] faces) and return the file's
// bytes; `binary` selects the binary variant where the format has one.
#pragma once

#include <string>
#include <string_view>

#include "pumeta/geometry/point_cloud.h"

namespace pumeta::io {

/// The message for .laz files and LAS files whose header sets the compression bits.
inline constexpr char kLazUnsupported[] =
    "LAZ (compressed LAS) is not supported; decompress it first with laszip "
    "(laszip -i in.laz -o out.las)";

Geometry read_ply(const std::string& path, std::string_view data);
std::string write_ply(const Geometry& geometry, bool binary);

Geometry read_xyz(const std::string& path, std::string_view data);
std::string write_xyz(const Geometry& geometry, bool binary);

Geometry read_off(const std::string& path, std::string_view data);
std::string write_off(const Geometry& geometry, bool binary);

Geometry read_obj(const std::string& path, std::string_view data);
std::string write_obj(const Geometry& geometry, bool binary);

Geometry read_stl(const std::string& path, std::string_view data);

Geometry read_pcd(const std::string& path, std::string_view data);
std::string write_pcd(const Geometry& geometry, bool binary);

Geometry read_las(const std::string& path, std::string_view data);

}  // namespace pumeta::io
