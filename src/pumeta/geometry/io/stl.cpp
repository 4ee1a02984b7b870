// STL, ascii ("solid ... facet normal ... outer loop / vertex x y z ... endsolid") and binary
// (80-byte header, uint32 triangle count, 50 bytes per triangle). STL stores each triangle's
// corners separately; identical corners are merged so that the mesh comes back indexed.
#include <ATen/ATen.h>

#include <cstring>
#include <unordered_map>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/binary.h"
#include "pumeta/geometry/io/formats.h"
#include "pumeta/geometry/io/mesh_builder.h"
#include "pumeta/geometry/io/text.h"

namespace pumeta::io {

namespace {

constexpr size_t kHeaderBytes = 84;
constexpr size_t kTriangleBytes = 50;

// Merges corners by their exact coordinates; -0 and +0 count as the same coordinate.
class VertexMerger {
  public:
    explicit VertexMerger(size_t corners) {
        index_.reserve(corners);
        points_.reserve(corners);
    }

    int64_t add(float x, float y, float z) {
        Key key{bits(x), bits(y), bits(z)};
        auto [it, inserted] = index_.try_emplace(key, static_cast<int64_t>(points_.size() / 3));
        if (inserted) points_.insert(points_.end(), {x, y, z});
        return it->second;
    }

    const std::vector<float>& points() const { return points_; }

  private:
    struct Key {
        uint32_t x, y, z;
        bool operator==(const Key& other) const {
            return x == other.x && y == other.y && z == other.z;
        }
    };
    struct KeyHash {
        size_t operator()(const Key& key) const {
            uint64_t h = key.x * 0x9E3779B97F4A7C15ull;
            h ^= (h >> 29) + key.y * 0xBF58476D1CE4E5B9ull;
            h ^= (h >> 31) + key.z * 0x94D049BB133111EBull;
            return static_cast<size_t>(h ^ (h >> 32));
        }
    };
    static uint32_t bits(float value) {
        value += 0.0f;  // turns -0 into +0
        uint32_t result;
        std::memcpy(&result, &value, 4);
        return result;
    }

    std::unordered_map<Key, int64_t, KeyHash> index_;
    std::vector<float> points_;
};

Geometry finish(const VertexMerger& merger, const std::vector<int64_t>& corners) {
    Geometry geometry;
    geometry.cloud.points = rows_tensor(merger.points());
    geometry.faces = at::empty({static_cast<int64_t>(corners.size() / 3), 3}, at::kLong);
    std::copy(corners.begin(), corners.end(), geometry.faces.data_ptr<int64_t>());
    return geometry;
}

Geometry read_binary(std::string_view data, uint32_t count) {
    VertexMerger merger(3 * static_cast<size_t>(count));
    std::vector<int64_t> corners(3 * static_cast<size_t>(count));
    for (size_t t = 0; t < count; ++t) {
        // 12 bytes of facet normal precede the three corners.
        const char* corner = data.data() + kHeaderBytes + t * kTriangleBytes + 12;
        for (int k = 0; k < 3; ++k, corner += 12)
            corners[3 * t + k] =
                merger.add(load<float>(corner), load<float>(corner + 4), load<float>(corner + 8));
    }
    return finish(merger, corners);
}

Geometry read_ascii(const std::string& path, std::string_view data) {
    LineReader lines(data);
    std::vector<std::string_view> tokens;
    VertexMerger merger(data.size() / 64);  // a corner line takes at least ~20 bytes of ~60
    std::vector<int64_t> corners;
    int64_t facet_line = 0;  // line of the open "facet", 0 outside a facet
    size_t facet_corners = 0;
    std::string_view line;
    while (lines.next_content(line)) {
        split_tokens(line, tokens);
        const int64_t number = lines.line_number();
        const std::string_view keyword = tokens[0];
        if (keyword == "vertex") {
            if (!facet_line) throw_input_error(path, "line {}: 'vertex' outside a facet", number);
            if (tokens.size() != 4)
                throw_input_error(path, "line {}: expected 'vertex x y z', found '{}'", number,
                                  printable(line));
            float xyz[3];
            for (int axis = 0; axis < 3; ++axis)
                xyz[axis] = parse_or_throw<float>(tokens[1 + axis], path, number, "a coordinate");
            corners.push_back(merger.add(xyz[0], xyz[1], xyz[2]));
            ++facet_corners;
        } else if (keyword == "facet") {
            if (facet_line)
                throw_input_error(path, "line {}: 'facet' before the 'endfacet' of line {}'s facet",
                                  number, facet_line);
            facet_line = number;
            facet_corners = 0;
        } else if (keyword == "endfacet") {
            if (facet_corners != 3)
                throw_input_error(path, "line {}: a facet needs 3 vertices, found {}", number,
                                  facet_corners);
            facet_line = 0;
        } else if (keyword != "solid" && keyword != "endsolid" && keyword != "outer" &&
                   keyword != "endloop") {
            throw_input_error(path, "line {}: unexpected '{}' in an ascii STL file", number,
                              printable(keyword));
        }
    }
    if (facet_line)
        throw_input_error(path, "the file ends inside the facet of line {}", facet_line);
    if (corners.empty()) throw_input_error(path, "the STL file contains no triangles");
    return finish(merger, corners);
}

}  // namespace

// A binary file may begin with "solid" too (many exporters write it into the header), so the
// size decides: binary when it is exactly 84 + 50 * (declared triangle count).
Geometry read_stl(const std::string& path, std::string_view data) {
    const bool starts_solid = trim(data.substr(0, 64)).substr(0, 5) == "solid";
    if (data.size() >= kHeaderBytes) {
        const uint32_t count = load<uint32_t>(data.data() + 80);
        const uint64_t expected = kHeaderBytes + uint64_t{count} * kTriangleBytes;
        if (expected == data.size()) {
            if (count == 0) throw_input_error(path, "the STL file contains no triangles");
            return read_binary(data, count);
        }
        // Text never holds NUL bytes: a "solid" file with them is a binary one of the wrong size.
        const bool looks_binary = std::memchr(data.data(), '\0', data.size()) != nullptr;
        if (!starts_solid || looks_binary)
            throw_input_error(path,
                              "binary STL declares {} triangles ({} bytes), but the file has {} "
                              "bytes",
                              count, expected, data.size());
    }
    if (!starts_solid)
        throw_input_error(path,
                          "not an STL file: {} bytes, too short for a binary STL and no "
                          "'solid' at the start",
                          data.size());
    return read_ascii(path, data);
}

}  // namespace pumeta::io
