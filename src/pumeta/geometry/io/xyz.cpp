// XYZ text clouds (.xyz, .txt, .pts): one point per line, "x y z" or "x y z nx ny nz",
// separated by blanks or commas, optionally preceded by a line holding only the point count.
// Blank lines and lines starting with '#' are skipped.
#include <ATen/ATen.h>
#include <fmt/format.h>

#include <iterator>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/formats.h"
#include "pumeta/geometry/io/mesh_builder.h"
#include "pumeta/geometry/io/text.h"

namespace pumeta::io {

Geometry read_xyz(const std::string& path, std::string_view data) {
    LineReader lines(data);
    std::vector<std::string_view> tokens;
    std::vector<float> points, normals;
    size_t columns = 0;  // fixed by the first point line
    int64_t declared = -1, declared_line = 0;
    std::string_view line;
    while (lines.next_content(line, '#')) {
        split_tokens(line, tokens, /*comma_separates=*/true);
        const int64_t number = lines.line_number();
        if (columns == 0 && declared < 0 && points.empty() && tokens.size() == 1) {
            declared = parse_or_throw<int64_t>(tokens[0], path, number, "a point count");
            declared_line = number;
            if (declared < 0)
                throw_input_error(path, "line {}: negative point count {}", number, declared);
            continue;
        }
        if (columns == 0) {
            if (tokens.size() != 3 && tokens.size() != 6)
                throw_input_error(path,
                                  "line {}: expected 3 columns (x y z) or 6 (x y z nx ny nz), "
                                  "found {}",
                                  number, tokens.size());
            columns = tokens.size();
            // Enough for the whole file when lines are alike, without trusting a count line.
            const size_t estimate = data.size() / std::max<size_t>(line.size() + 1, 1);
            points.reserve(3 * estimate);
            if (columns == 6) normals.reserve(3 * estimate);
        } else if (tokens.size() != columns) {
            throw_input_error(path, "line {}: expected {} columns like the first point, found {}",
                              number, columns, tokens.size());
        }
        for (int axis = 0; axis < 3; ++axis)
            points.push_back(parse_or_throw<float>(tokens[axis], path, number, "a coordinate"));
        if (columns == 6)
            for (int axis = 3; axis < 6; ++axis)
                normals.push_back(
                    parse_or_throw<float>(tokens[axis], path, number, "a normal component"));
    }
    const int64_t count = static_cast<int64_t>(points.size() / 3);
    if (declared >= 0 && declared != count)
        throw_input_error(path, "line {}: the count line declares {} points, the file has {}",
                          declared_line, declared, count);
    Geometry geometry;
    geometry.cloud.points = rows_tensor(points);
    if (columns == 6) geometry.cloud.normals = rows_tensor(normals);
    return geometry;
}

std::string write_xyz(const Geometry& geometry, bool /*binary*/) {
    const PointCloud& cloud = geometry.cloud;
    const float* points = cloud.points.data_ptr<float>();
    const float* normals = cloud.has_normals() ? cloud.normals.data_ptr<float>() : nullptr;
    std::string out;
    for (int64_t i = 0; i < cloud.size(); ++i) {
        const float* p = points + 3 * i;
        fmt::format_to(std::back_inserter(out), "{} {} {}", p[0], p[1], p[2]);
        if (normals) {
            const float* q = normals + 3 * i;
            fmt::format_to(std::back_inserter(out), " {} {} {}", q[0], q[1], q[2]);
        }
        out += '\n';
    }
    return out;
}

}  // namespace pumeta::io
