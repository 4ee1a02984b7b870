// LAS 1.0-1.4, uncompressed, point data formats 0-10: every record starts with int32 X, Y, Z
// which the header's scale and offset turn into coordinates; formats with RGB carry colours.
// Variable-length records are skipped through the header's offset to the point data.
#include <ATen/ATen.h>

#include <algorithm>
#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/geometry/io/binary.h"
#include "pumeta/geometry/io/formats.h"

namespace pumeta::io {

namespace {

// Byte offsets of the public header block fields used here (LAS 1.4 specification, table 3).
constexpr size_t kVersionMajor = 24;
constexpr size_t kVersionMinor = 25;
constexpr size_t kHeaderSize = 94;
constexpr size_t kOffsetToPoints = 96;
constexpr size_t kPointFormat = 104;
constexpr size_t kRecordLength = 105;
constexpr size_t kLegacyPointCount = 107;
constexpr size_t kScale = 131;
constexpr size_t kOffset = 155;
constexpr size_t kPointCount14 = 247;
constexpr size_t kMinHeaderBytes = 227;  // LAS 1.0-1.2
constexpr size_t kHeaderBytes14 = 375;   // LAS 1.4

// Smallest record of each point data format, and where its RGB sits (0: no colour).
constexpr size_t kMinRecordBytes[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
constexpr size_t kColorOffset[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

}  // namespace

Geometry read_las(const std::string& path, std::string_view data) {
    if (data.size() < 4 || data.substr(0, 4) != "LASF")
        throw_input_error(path, "not a LAS file (no 'LASF' signature)");
    if (data.size() < kMinHeaderBytes)
        throw_input_error(path, "truncated LAS header: {} bytes, at least {} needed", data.size(),
                          kMinHeaderBytes);
    const char* header = data.data();
    const int major = load<uint8_t>(header + kVersionMajor);
    const int minor = load<uint8_t>(header + kVersionMinor);
    if (major != 1 || minor > 4)
        throw_input_error(path, "unsupported LAS version {}.{} (1.0 to 1.4 are supported)", major,
                          minor);
    const uint8_t format_byte = load<uint8_t>(header + kPointFormat);
    // LASzip marks compressed point data by setting the top bits of the format id.
    if (format_byte & 0xC0) throw_input_error(path, "{}", kLazUnsupported);
    const int format = format_byte;
    if (format > 10)
        throw_input_error(path, "unsupported LAS point data format {} (0 to 10 are supported)",
                          format);
    const size_t header_size = load<uint16_t>(header + kHeaderSize);
    const size_t offset_to_points = load<uint32_t>(header + kOffsetToPoints);
    const size_t record_length = load<uint16_t>(header + kRecordLength);
    uint64_t count = load<uint32_t>(header + kLegacyPointCount);
    if (minor >= 4) {
        if (header_size < kHeaderBytes14 || data.size() < kHeaderBytes14)
            throw_input_error(path, "LAS 1.4 header of {} bytes, at least {} needed",
                              std::min<size_t>(header_size, data.size()), kHeaderBytes14);
        count = load<uint64_t>(header + kPointCount14);
    }
    if (header_size < kMinHeaderBytes)
        throw_input_error(path, "LAS header size {} is below the minimum {}", header_size,
                          kMinHeaderBytes);
    if (record_length < kMinRecordBytes[format])
        throw_input_error(path,
                          "point data format {} needs records of at least {} bytes, the header "
                          "declares {}",
                          format, kMinRecordBytes[format], record_length);
    if (offset_to_points < header_size || offset_to_points > data.size())
        throw_input_error(path, "offset to point data {} is outside [{}, {}]", offset_to_points,
                          header_size, data.size());
    const size_t available = data.size() - offset_to_points;
    if (count > available / record_length)
        throw_input_error(path,
                          "truncated LAS: the header declares {} points of {} bytes from byte "
                          "offset {}, but only {} bytes follow",
                          count, record_length, offset_to_points, available);
    double scale[3], offset[3];
    for (int axis = 0; axis < 3; ++axis) {
        scale[axis] = load<double>(header + kScale + 8 * axis);
        offset[axis] = load<double>(header + kOffset + 8 * axis);
        if (!std::isfinite(scale[axis]) || scale[axis] == 0 || !std::isfinite(offset[axis]))
            throw_input_error(path, "invalid {} scale {} or offset {} in the LAS header",
                              "xyz"[axis], scale[axis], offset[axis]);
    }

    const int64_t n = static_cast<int64_t>(count);
    const char* records = data.data() + offset_to_points;
    at::Tensor points = at::empty({n, 3}, at::kFloat);
    float* p = points.data_ptr<float>();
    for (int64_t i = 0; i < n; ++i) {
        const char* record = records + i * record_length;
        for (int axis = 0; axis < 3; ++axis)
            p[3 * i + axis] =
                static_cast<float>(load<int32_t>(record + 4 * axis) * scale[axis] + offset[axis]);
    }
    at::Tensor colors;
    if (kColorOffset[format]) {
        // LAS colours are 16-bit, but some writers store 8-bit values unscaled.
        std::vector<uint16_t> rgb(3 * n);
        for (int64_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c)
                rgb[3 * i + c] =
                    load<uint16_t>(records + i * record_length + kColorOffset[format] + 2 * c);
        const bool sixteen_bit =
            std::any_of(rgb.begin(), rgb.end(), [](uint16_t v) { return v > 255; });
        colors = at::empty({n, 3}, at::kByte);
        uint8_t* out = colors.data_ptr<uint8_t>();
        for (size_t k = 0; k < rgb.size(); ++k)
            out[k] = static_cast<uint8_t>(sixteen_bit ? rgb[k] >> 8 : rgb[k]);
    }
    return {{points, at::Tensor(), colors}, at::Tensor()};
}

}  // namespace pumeta::io
