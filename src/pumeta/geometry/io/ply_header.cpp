// PLY header parsing: the format line, elements and their properties.
#include "pumeta/core/error.h"
#include "pumeta/geometry/io/ply_format.h"
#include "pumeta/geometry/io/text.h"

namespace pumeta::io::ply {

namespace {

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

ScalarType parse_type(std::string_view name, const std::string& path, int64_t line) {
    for (const TypeName& entry : kTypeNames)
        if (name == entry.name) return entry.type;
    throw_input_error(path, "line {}: unknown PLY property type '{}'", line, printable(name));
}

}  // namespace

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

}  // namespace pumeta::io::ply
