#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <array>
#include <cstring>

#include "geometry/io_test_util.h"
#include "pumeta/geometry/io.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::throws_input_error;

// Writes `value` at byte `offset` of `bytes` (little endian, as LAS stores everything).
template <typename T>
void poke(std::string& bytes, size_t offset, T value) {
    std::memcpy(&bytes[offset], &value, sizeof(T));
}

struct LasFile {
    int minor = 2;
    uint8_t format = 1;
    uint16_t record_length = 28;
    std::vector<std::array<int32_t, 3>> xyz;
    std::vector<std::array<uint16_t, 3>> rgb;  // formats with colour only
    double scale[3] = {0.01, 0.01, 0.001};
    double offset[3] = {1000, -200, 5};
    uint16_t vlr_payload = 0;  // one variable-length record of this many bytes, 0 for none

    // The file byte by byte, following the LAS 1.4 R15 specification's tables.
    std::string bytes() const {
        const uint16_t header_size = minor >= 4 ? 375 : 227;
        const uint32_t vlr_bytes = vlr_payload ? 54 + vlr_payload : 0;
        std::string out(header_size, '\0');
        std::memcpy(&out[0], "LASF", 4);
        poke<uint8_t>(out, 24, 1);
        poke<uint8_t>(out, 25, static_cast<uint8_t>(minor));
        std::memcpy(&out[26], "pumeta test", 11);
        poke<uint16_t>(out, 94, header_size);
        poke<uint32_t>(out, 96, header_size + vlr_bytes);
        poke<uint32_t>(out, 100, vlr_payload ? 1 : 0);
        poke<uint8_t>(out, 104, format);
        poke<uint16_t>(out, 105, record_length);
        // LAS 1.4 keeps the legacy 32-bit count at 0 for formats 6-10.
        poke<uint32_t>(out, 107, minor >= 4 ? 0 : static_cast<uint32_t>(xyz.size()));
        for (int axis = 0; axis < 3; ++axis) {
            poke<double>(out, 131 + 8 * axis, scale[axis]);
            poke<double>(out, 155 + 8 * axis, offset[axis]);
        }
        if (minor >= 4) poke<uint64_t>(out, 247, xyz.size());
        if (vlr_payload) {
            std::string vlr(vlr_bytes, '\x7f');  // junk a reader must skip
            poke<uint16_t>(vlr, 20, vlr_payload);
            out += vlr;
        }
        const size_t color_offset = format == 2 ? 20 : format == 3 ? 28 : format == 7 ? 30 : 0;
        for (size_t i = 0; i < xyz.size(); ++i) {
            std::string record(record_length, '\x55');
            for (int axis = 0; axis < 3; ++axis) poke<int32_t>(record, 4 * axis, xyz[i][axis]);
            if (color_offset)
                for (int c = 0; c < 3; ++c) poke<uint16_t>(record, color_offset + 2 * c, rgb[i][c]);
            out += record;
        }
        return out;
    }

    // float32 [N,3]: X * scale + offset, computed in double like the reader's contract says.
    at::Tensor expected() const {
        at::Tensor points = at::empty({static_cast<int64_t>(xyz.size()), 3}, at::kFloat);
        for (size_t i = 0; i < xyz.size(); ++i)
            for (int axis = 0; axis < 3; ++axis)
                points[i][axis] = static_cast<float>(xyz[i][axis] * scale[axis] + offset[axis]);
        return points;
    }
};

TEST(IoLas, Las12Format1WithVlrAndLongRecordsAppliesScaleAndOffset) {
    test::TempDir dir;
    LasFile las;
    las.record_length = 32;  // 4 bytes of extra data per point that the reader must step over
    las.vlr_payload = 40;
    las.xyz = {{0, 0, 0}, {12345, -67, 2000}, {-100000, 99, -1}};
    const std::string path = dir.file("f1.las");
    test::write_file(path, las.bytes());
    const PointCloud cloud = read_point_cloud(path);
    EXPECT_TRUE(at::equal(cloud.points, las.expected())) << cloud.points;
    // Hand-computed: 12345 * 0.01 + 1000 = 1123.45, -67 * 0.01 - 200 = -200.67, 2 + 5 = 7.
    EXPECT_FLOAT_EQ(cloud.points[1][0].item<float>(), 1123.45f);
    EXPECT_FLOAT_EQ(cloud.points[1][1].item<float>(), -200.67f);
    EXPECT_FLOAT_EQ(cloud.points[1][2].item<float>(), 7.f);
    EXPECT_FALSE(cloud.has_colors());
}

TEST(IoLas, Las14Format6UsesThe64BitPointCount) {
    test::TempDir dir;
    LasFile las;
    las.minor = 4;
    las.format = 6;
    las.record_length = 30;
    las.scale[0] = las.scale[1] = las.scale[2] = 0.5;
    las.offset[0] = las.offset[1] = las.offset[2] = -1;
    las.xyz = {{2, 4, 6}, {-2, 0, 1}};
    const std::string path = dir.file("f6.las");
    test::write_file(path, las.bytes());
    const PointCloud cloud = read_point_cloud(path);
    EXPECT_TRUE(at::equal(cloud.points, test::float_rows({0, 1, 2, -2, -1, -0.5f})));
}

TEST(IoLas, RgbFormatsCarryColoursScaledTo8Bits) {
    test::TempDir dir;
    for (uint8_t format : {2, 3, 7}) {
        LasFile las;
        las.minor = format == 7 ? 4 : 2;
        las.format = format;
        las.record_length = format == 2 ? 26 : format == 3 ? 34 : 36;
        las.xyz = {{1, 2, 3}, {4, 5, 6}};
        las.rgb = {{65535, 256, 0}, {32768, 0, 512}};
        const std::string path = dir.file("rgb.las");
        test::write_file(path, las.bytes());
        const PointCloud cloud = read_point_cloud(path);
        EXPECT_TRUE(at::equal(cloud.points, las.expected()));
        ASSERT_TRUE(cloud.has_colors()) << int(format);
        EXPECT_TRUE(at::equal(
            cloud.colors, at::tensor({255, 1, 0, 128, 0, 2}, at::kInt).to(at::kByte).view({2, 3})))
            << int(format);
    }
}

TEST(IoLas, CompressedUnsupportedAndTruncatedFilesAreReported) {
    test::TempDir dir;
    const std::string path = dir.file("bad.las");
    LasFile las;
    las.xyz = {{1, 2, 3}, {4, 5, 6}};
    std::string bytes = las.bytes();

    std::string laz = bytes;
    poke<uint8_t>(laz, 104, 0x80 | 1);  // LASzip's compression bit
    test::write_file(path, laz);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "LAZ (compressed LAS) is not supported", "laszip"}));

    test::write_file(path, bytes.substr(0, bytes.size() - 1));
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "truncated LAS", "2 points of 28 bytes",
                                    "byte offset 227", "only 55 bytes follow"}));

    std::string huge = bytes;
    poke<uint32_t>(huge, 107, 4000000000u);
    test::write_file(path, huge);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "4000000000 points"}));

    std::string format = bytes;
    poke<uint8_t>(format, 104, 11);
    test::write_file(path, format);
    EXPECT_TRUE(
        throws_input_error([&] { read_point_cloud(path); }, {path, "point data format 11"}));

    std::string record = bytes;
    poke<uint16_t>(record, 105, 20);
    test::write_file(path, record);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "format 1 needs records of at least 28 bytes"}));

    std::string version = bytes;
    poke<uint8_t>(version, 24, 2);
    test::write_file(path, version);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "LAS version 2.2"}));

    std::string scale = bytes;
    poke<double>(scale, 139, 0.0);
    test::write_file(path, scale);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "invalid y scale 0"}));

    test::write_file(path, "LASF" + std::string(100, '\0'));
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "truncated LAS header: 104 bytes"}));
    test::write_file(path, "PK\x03\x04 not a las file");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "not a LAS file"}));
}

}  // namespace
}  // namespace pumeta
