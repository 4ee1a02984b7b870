// PLY (Stanford polygon file format): ascii, binary little endian and binary big endian.
// Vertices carry x,y,z, optionally nx,ny,nz and red,green,blue; faces come from the
// `vertex_indices` (or `vertex_index`) list of the "face" element; every other element and
// property is skipped.
//
// The header parser is in ply_header.cpp, the body readers in ply_ascii.cpp and ply_binary.cpp,
// the mapping of elements onto vertices and faces in ply_layout.cpp, the writer in
// ply_writer.cpp; ply_format.h holds what they share.
#include "pumeta/geometry/io/formats.h"
#include "pumeta/geometry/io/ply_format.h"

namespace pumeta::io {

Geometry read_ply(const std::string& path, std::string_view data) {
    const ply::Header header = ply::parse_header(path, data);
    if (header.encoding == ply::Encoding::Ascii) return ply::read_ascii(path, data, header);
    return ply::read_binary(path, data, header);
}

}  // namespace pumeta::io
