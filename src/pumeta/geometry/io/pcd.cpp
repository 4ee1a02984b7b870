// PCD (Point Cloud Library): a text header (FIELDS/SIZE/TYPE/COUNT/WIDTH/HEIGHT/POINTS/DATA)
// followed by ascii lines or packed binary records. x, y, z are required; normal_x/y/z and a
// packed rgb/rgba field (0x00RRGGBB in 4 bytes) are carried; other fields are skipped.
#include <ATen/ATen.h>
#include <fmt/format.h>

#include <cstring>
#include <iterator>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/binary.h"
#include "pumeta/geometry/io/formats.h"
#include "pumeta/geometry/io/text.h"

namespace pumeta::io {

namespace {

struct Field {
    std::string name;
    size_t size = 4;
    char type = 'F';
    size_t count = 1;
    size_t offset = 0;  // byte offset in a binary record
    size_t token = 0;   // index of its first value in an ascii line
};

enum class Encoding { Ascii, Binary };

struct Header {
    std::vector<Field> fields;
    uint64_t points = 0;
    Encoding encoding = Encoding::Ascii;
    size_t record_bytes = 0;
    size_t record_tokens = 0;
    size_t data_offset = 0;
    int64_t header_lines = 0;
};

// A field of more values than this is not a point attribute (PCL's largest descriptors, such
// as the 1,980 values of SHOT with colour, stay far below); it also keeps record sizes and
// offsets far from overflow.
constexpr size_t kMaxFieldCount = 1 << 16;

uint64_t parse_count(std::string_view token, const std::string& path, int64_t line,
                     const char* what) {
    const int64_t value = parse_or_throw<int64_t>(token, path, line, what);
    if (value < 0) throw_input_error(path, "line {}: negative {} {}", line, what, value);
    return static_cast<uint64_t>(value);
}

Header parse_header(const std::string& path, std::string_view data) {
    Header header;
    LineReader lines(data);
    std::vector<std::string_view> tokens;
    std::vector<size_t> sizes, counts;
    std::vector<char> types;
    uint64_t width = 0, height = 1;
    bool have_points = false;
    std::string_view line;
    while (lines.next_content(line, '#')) {
        split_tokens(line, tokens);
        const int64_t number = lines.line_number();
        const std::string_view keyword = tokens[0];
        if (keyword == "FIELDS" || keyword == "COLUMNS") {
            for (size_t i = 1; i < tokens.size(); ++i)
                header.fields.push_back({std::string(tokens[i])});
        } else if (keyword == "SIZE" || keyword == "COUNT") {
            std::vector<size_t>& target = keyword == "SIZE" ? sizes : counts;
            for (size_t i = 1; i < tokens.size(); ++i)
                target.push_back(parse_count(tokens[i], path, number, "field size or count"));
        } else if (keyword == "TYPE") {
            for (size_t i = 1; i < tokens.size(); ++i) {
                if (tokens[i].size() != 1)
                    throw_input_error(path, "line {}: unknown field type '{}'", number,
                                      printable(tokens[i]));
                types.push_back(tokens[i][0]);
            }
        } else if (keyword == "WIDTH" && tokens.size() == 2) {
            width = parse_count(tokens[1], path, number, "width");
        } else if (keyword == "HEIGHT" && tokens.size() == 2) {
            height = parse_count(tokens[1], path, number, "height");
        } else if (keyword == "POINTS" && tokens.size() == 2) {
            header.points = parse_count(tokens[1], path, number, "point count");
            have_points = true;
        } else if (keyword == "DATA" && tokens.size() == 2) {
            if (tokens[1] == "binary_compressed")
                throw_input_error(path,
                                  "line {}: binary_compressed PCD is not supported; convert it "
                                  "to binary or ascii first (e.g. pcl_convert_pcd_ascii_binary)",
                                  number);
            if (tokens[1] == "ascii") {
                header.encoding = Encoding::Ascii;
            } else if (tokens[1] == "binary") {
                header.encoding = Encoding::Binary;
            } else {
                throw_input_error(path, "line {}: unknown DATA encoding '{}'", number,
                                  printable(tokens[1]));
            }
            header.data_offset = lines.offset();
            header.header_lines = number;
            break;
        } else if (keyword != "VERSION" && keyword != "VIEWPOINT") {
            throw_input_error(path, "line {}: unexpected PCD header line '{}'", number,
                              printable(line));
        }
    }
    if (header.data_offset == 0) throw_input_error(path, "the PCD header has no DATA line");
    const size_t n = header.fields.size();
    if (n == 0) throw_input_error(path, "the PCD header has no FIELDS line");
    if (counts.empty()) counts.assign(n, 1);
    if (sizes.size() != n || types.size() != n || counts.size() != n)
        throw_input_error(path,
                          "the PCD header lists {} FIELDS but {} SIZE, {} TYPE and {} COUNT "
                          "entries",
                          n, sizes.size(), types.size(), counts.size());
    for (size_t i = 0; i < n; ++i) {
        Field& field = header.fields[i];
        field.size = sizes[i];
        field.type = types[i];
        field.count = counts[i];
        const bool valid =
            field.type == 'F' ? (field.size == 4 || field.size == 8)
            : (field.type == 'I' || field.type == 'U')
                ? (field.size == 1 || field.size == 2 || field.size == 4 || field.size == 8)
                : false;
        if (!valid)
            throw_input_error(path, "field '{}' has an unsupported TYPE {} with SIZE {}",
                              field.name, field.type, field.size);
        if (field.count == 0 || field.count > kMaxFieldCount)
            throw_input_error(path, "field '{}' has COUNT {}; expected 1 to {}", field.name,
                              field.count, kMaxFieldCount);
        field.offset = header.record_bytes;
        field.token = header.record_tokens;
        // Bounded by kMaxFieldCount * 8 bytes per field and the number of header tokens, so
        // neither sum can wrap.
        header.record_bytes += field.size * field.count;
        header.record_tokens += field.count;
    }
    if (!have_points) header.points = width * height;
    return header;
}

double load_field(const char* bytes, const Field& field) {
    switch (field.type) {
        case 'F':
            return field.size == 4 ? load<float>(bytes) : load<double>(bytes);
        case 'I':
            switch (field.size) {
                case 1:
                    return load<int8_t>(bytes);
                case 2:
                    return load<int16_t>(bytes);
                case 4:
                    return load<int32_t>(bytes);
                default:
                    return static_cast<double>(load<int64_t>(bytes));
            }
        default:
            switch (field.size) {
                case 1:
                    return load<uint8_t>(bytes);
                case 2:
                    return load<uint16_t>(bytes);
                case 4:
                    return load<uint32_t>(bytes);
                default:
                    return static_cast<double>(load<uint64_t>(bytes));
            }
    }
}

void unpack_rgb(uint32_t packed, uint8_t* color) {
    color[0] = static_cast<uint8_t>(packed >> 16);
    color[1] = static_cast<uint8_t>(packed >> 8);
    color[2] = static_cast<uint8_t>(packed);
}

// Indices of the fields the reader uses: xyz, normals (all three or none), colour.
struct Layout {
    int xyz[3] = {-1, -1, -1};
    int normal[3] = {-1, -1, -1};
    int color = -1;
    bool has_normals() const { return normal[0] >= 0; }
};

Layout find_fields(const std::string& path, const Header& header) {
    Layout layout;
    const char* xyz_names[3] = {"x", "y", "z"};
    const char* normal_names[3] = {"normal_x", "normal_y", "normal_z"};
    for (size_t i = 0; i < header.fields.size(); ++i) {
        const Field& field = header.fields[i];
        for (int axis = 0; axis < 3; ++axis) {
            if (field.name == xyz_names[axis]) layout.xyz[axis] = static_cast<int>(i);
            if (field.name == normal_names[axis]) layout.normal[axis] = static_cast<int>(i);
        }
        if ((field.name == "rgb" || field.name == "rgba") && field.size == 4 && field.count == 1)
            layout.color = static_cast<int>(i);
    }
    for (int axis = 0; axis < 3; ++axis) {
        if (layout.xyz[axis] < 0)
            throw_input_error(path, "the PCD file has no '{}' field", xyz_names[axis]);
        if (header.fields[layout.xyz[axis]].count != 1)
            throw_input_error(path, "field '{}' must have COUNT 1", xyz_names[axis]);
    }
    bool normals = true;
    for (int axis = 0; axis < 3; ++axis)
        normals =
            normals && layout.normal[axis] >= 0 && header.fields[layout.normal[axis]].count == 1;
    if (!normals) layout.normal[0] = layout.normal[1] = layout.normal[2] = -1;
    return layout;
}

Geometry read_binary(std::string_view data, const Header& header, const Layout& layout,
                     PointCloud cloud) {
    const char* base = data.data() + header.data_offset;
    const size_t stride = header.record_bytes;
    const int64_t n = static_cast<int64_t>(header.points);
    float* points = cloud.points.data_ptr<float>();
    const Field& x = header.fields[layout.xyz[0]];
    const bool packed =
        x.type == 'F' && x.size == 4 && header.fields[layout.xyz[1]].offset == x.offset + 4 &&
        header.fields[layout.xyz[2]].offset == x.offset + 8 &&
        header.fields[layout.xyz[1]].type == 'F' && header.fields[layout.xyz[1]].size == 4 &&
        header.fields[layout.xyz[2]].type == 'F' && header.fields[layout.xyz[2]].size == 4;
    for (int64_t i = 0; i < n; ++i) {
        const char* record = base + i * stride;
        if (packed) {
            std::memcpy(points + 3 * i, record + x.offset, 12);
        } else {
            for (int axis = 0; axis < 3; ++axis) {
                const Field& field = header.fields[layout.xyz[axis]];
                points[3 * i + axis] = static_cast<float>(load_field(record + field.offset, field));
            }
        }
        if (layout.has_normals()) {
            float* normal = cloud.normals.data_ptr<float>() + 3 * i;
            for (int axis = 0; axis < 3; ++axis) {
                const Field& field = header.fields[layout.normal[axis]];
                normal[axis] = static_cast<float>(load_field(record + field.offset, field));
            }
        }
        if (layout.color >= 0)
            unpack_rgb(load<uint32_t>(record + header.fields[layout.color].offset),
                       cloud.colors.data_ptr<uint8_t>() + 3 * i);
    }
    return {cloud, at::Tensor()};
}

Geometry read_ascii(const std::string& path, std::string_view data, const Header& header,
                    const Layout& layout, PointCloud cloud) {
    LineReader lines(data, header.data_offset, header.header_lines);
    std::vector<std::string_view> tokens;
    std::string_view line;
    float* points = cloud.points.data_ptr<float>();
    float* normals = layout.has_normals() ? cloud.normals.data_ptr<float>() : nullptr;
    uint8_t* colors = layout.color >= 0 ? cloud.colors.data_ptr<uint8_t>() : nullptr;
    for (uint64_t i = 0; i < header.points; ++i) {
        if (!lines.next_content(line))
            throw_input_error(path, "line {}: the file ends after {} of the {} points declared",
                              lines.line_number(), i, header.points);
        split_tokens(line, tokens);
        const int64_t number = lines.line_number();
        if (tokens.size() < header.record_tokens)
            throw_input_error(path, "line {}: expected {} values, found {}", number,
                              header.record_tokens, tokens.size());
        for (int axis = 0; axis < 3; ++axis) {
            points[3 * i + axis] = parse_or_throw<float>(
                tokens[header.fields[layout.xyz[axis]].token], path, number, "a coordinate");
            if (normals)
                normals[3 * i + axis] =
                    parse_or_throw<float>(tokens[header.fields[layout.normal[axis]].token], path,
                                          number, "a normal component");
        }
        if (colors) {
            const Field& field = header.fields[layout.color];
            const std::string_view token = tokens[field.token];
            uint32_t packed;
            if (field.type == 'F') {
                // PCL writes the packed colour's bits reinterpreted as a float.
                const float value = parse_or_throw<float>(token, path, number, "a packed colour");
                std::memcpy(&packed, &value, 4);
            } else {
                packed = static_cast<uint32_t>(
                    parse_or_throw<int64_t>(token, path, number, "a packed colour"));
            }
            unpack_rgb(packed, colors + 3 * i);
        }
    }
    return {cloud, at::Tensor()};
}

}  // namespace

Geometry read_pcd(const std::string& path, std::string_view data) {
    const Header header = parse_header(path, data);
    const Layout layout = find_fields(path, header);
    // Declared counts larger than the data can hold must not reach the allocator: an ascii
    // point of k values takes at least 2k - 1 bytes, a binary one exactly record_bytes.
    const size_t available = data.size() - header.data_offset;
    if (header.encoding == Encoding::Ascii &&
        header.points > available / (2 * header.record_tokens - 1))
        throw_input_error(path,
                          "the header declares {} points, more than the {} bytes of data "
                          "can hold",
                          header.points, available);
    if (header.encoding == Encoding::Binary && header.points > available / header.record_bytes)
        throw_input_error(path,
                          "truncated binary PCD: the header declares {} points of {} bytes "
                          "from byte offset {}, but only {} bytes follow",
                          header.points, header.record_bytes, header.data_offset, available);
    const int64_t n = static_cast<int64_t>(header.points);
    PointCloud cloud;
    cloud.points = at::empty({n, 3}, at::kFloat);
    if (layout.has_normals()) cloud.normals = at::empty({n, 3}, at::kFloat);
    if (layout.color >= 0) cloud.colors = at::empty({n, 3}, at::kByte);
    return header.encoding == Encoding::Binary ? read_binary(data, header, layout, cloud)
                                               : read_ascii(path, data, header, layout, cloud);
}

std::string write_pcd(const Geometry& geometry, bool binary) {
    const PointCloud& cloud = geometry.cloud;
    const int64_t n = cloud.size();
    const float* points = cloud.points.data_ptr<float>();
    const float* normals = cloud.has_normals() ? cloud.normals.data_ptr<float>() : nullptr;
    const uint8_t* colors = cloud.has_colors() ? cloud.colors.data_ptr<uint8_t>() : nullptr;
    std::string fields = "x y z", sizes = "4 4 4", types = "F F F", counts = "1 1 1";
    if (normals) {
        fields += " normal_x normal_y normal_z";
        sizes += " 4 4 4";
        types += " F F F";
        counts += " 1 1 1";
    }
    if (colors) {
        // An unsigned integer rather than PCL's float-typed rgb: the ascii form stays readable
        // and needs no denormal float round trip.
        fields += " rgb";
        sizes += " 4";
        types += " U";
        counts += " 1";
    }
    std::string out;
    fmt::format_to(std::back_inserter(out),
                   "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {}\nSIZE {}\n"
                   "TYPE {}\nCOUNT {}\nWIDTH {}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {}\n"
                   "DATA {}\n",
                   fields, sizes, types, counts, n, n, binary ? "binary" : "ascii");
    auto packed_color = [&](int64_t i) {
        const uint8_t* c = colors + 3 * i;
        return (uint32_t{c[0]} << 16) | (uint32_t{c[1]} << 8) | uint32_t{c[2]};
    };
    if (binary) {
        out.reserve(out.size() + n * (12 + (normals ? 12 : 0) + (colors ? 4 : 0)));
        for (int64_t i = 0; i < n; ++i) {
            out.append(reinterpret_cast<const char*>(points + 3 * i), 12);
            if (normals) out.append(reinterpret_cast<const char*>(normals + 3 * i), 12);
            if (colors) append_le(out, packed_color(i));
        }
        return out;
    }
    for (int64_t i = 0; i < n; ++i) {
        const float* p = points + 3 * i;
        fmt::format_to(std::back_inserter(out), "{} {} {}", p[0], p[1], p[2]);
        if (normals) {
            const float* q = normals + 3 * i;
            fmt::format_to(std::back_inserter(out), " {} {} {}", q[0], q[1], q[2]);
        }
        if (colors) fmt::format_to(std::back_inserter(out), " {}", packed_color(i));
        out += '\n';
    }
    return out;
}

}  // namespace pumeta::io
