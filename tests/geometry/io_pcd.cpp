#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "geometry/io_test_util.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::float_rows;
using test::put_bytes;
using test::throws_input_error;

at::Tensor colors(const std::vector<int>& values) {
    return at::tensor(values, at::kInt).to(at::kByte).view({-1, 3});
}

TEST(IoPcd, RoundTripsInBinaryAndAscii) {
    test::TempDir dir;
    const int64_t n = 200;
    const PointCloud cloud{uniform_random_points(n, 21), uniform_random_points(n, 22),
                           (at::arange(3 * n, at::kLong) * 53 % 256).to(at::kByte).view({n, 3})};
    for (bool binary : {true, false}) {
        const std::string path = dir.file(binary ? "b.pcd" : "a.pcd");
        write_point_cloud(path, cloud, {"", binary});
        EXPECT_NE(test::read_file(path).find(binary ? "DATA binary\n" : "DATA ascii\n"),
                  std::string::npos);
        const PointCloud back = read_point_cloud(path);
        EXPECT_TRUE(at::equal(back.points, cloud.points));
        ASSERT_TRUE(back.has_normals() && back.has_colors());
        EXPECT_TRUE(at::equal(back.normals, cloud.normals));
        EXPECT_TRUE(at::equal(back.colors, cloud.colors));

        write_point_cloud(path, {cloud.points, {}, {}}, {"", binary});
        const PointCloud plain = read_point_cloud(path);
        EXPECT_TRUE(at::equal(plain.points, cloud.points));
        EXPECT_FALSE(plain.has_normals() || plain.has_colors());
    }
}

TEST(IoPcd, ReadsPclStyleAsciiWithFloatPackedColours) {
    const PointCloud cloud = read_point_cloud(test::io_fixture("pcl_style.pcd"));
    EXPECT_TRUE(at::equal(cloud.points, float_rows({0.5f, 1, -2, 3, 4, 5, -1, -1, -1})));
    EXPECT_TRUE(at::equal(cloud.normals, float_rows({0, 0, 1, 1, 0, 0, 0, 1, 0})));
    EXPECT_TRUE(at::equal(cloud.colors, colors({255, 128, 64, 10, 20, 30, 0, 0, 0})));
}

std::string binary_header(const std::string& fields, const std::string& sizes,
                          const std::string& types, const std::string& counts, int points) {
    return "# .PCD v0.7\nVERSION 0.7\nFIELDS " + fields + "\nSIZE " + sizes + "\nTYPE " + types +
           "\nCOUNT " + counts + "\nWIDTH " + std::to_string(points) +
           "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(points) +
           "\nDATA binary\n";
}

TEST(IoPcd, BinaryHonoursSizeTypeAndCount) {
    test::TempDir dir;
    // Padding and a leading field move x away from offset 0; x is a double and z an int16.
    std::string bytes =
        binary_header("intensity _ x y z rgba normal_x normal_y normal_z", "2 1 8 4 2 4 4 4 4",
                      "U U F F I U F F F", "1 3 1 1 1 1 1 1 1", 2);
    const double xs[2] = {1.5, -2.25};
    const float ys[2] = {3, 0.125f};
    const int16_t zs[2] = {-4, 7};
    const uint32_t rgba[2] = {0xFF102030u, 0x00FFFFFFu};
    for (int i = 0; i < 2; ++i) {
        put_bytes<uint16_t>(bytes, 1000);
        bytes += std::string("\x01\x02\x03", 3);
        put_bytes<double>(bytes, xs[i]);
        put_bytes<float>(bytes, ys[i]);
        put_bytes<int16_t>(bytes, zs[i]);
        put_bytes<uint32_t>(bytes, rgba[i]);
        for (float c : {0.f, 1.f, 0.f}) put_bytes<float>(bytes, c);
    }
    const std::string path = dir.file("typed.pcd");
    test::write_file(path, bytes);
    const PointCloud cloud = read_point_cloud(path);
    EXPECT_TRUE(at::equal(cloud.points, float_rows({1.5f, 3, -4, -2.25f, 0.125f, 7})));
    EXPECT_TRUE(at::equal(cloud.normals, float_rows({0, 1, 0, 0, 1, 0})));
    EXPECT_TRUE(at::equal(cloud.colors, colors({16, 32, 48, 255, 255, 255})));

    // One byte short of the two declared records.
    test::write_file(path, bytes.substr(0, bytes.size() - 1));
    EXPECT_TRUE(throws_input_error(
        [&] { read_point_cloud(path); },
        {path, "truncated binary PCD", "2 points of 35 bytes", "only 69 bytes follow"}));
}

// Found by fuzzing: a COUNT so large that the record size wrapped to 0 (a division by zero),
// fields of COUNT 0 read anyway, and offsets that wrapped to read outside the buffer.
TEST(IoPcd, FieldCountsAreBoundedAndOffsetsCannotWrap) {
    test::TempDir dir;
    const std::string path = dir.file("counts.pcd");
    // 4 bytes * 2^62 wraps a 64-bit record size to 0.
    test::write_file(
        path, binary_header("x y z w", "4 4 4 4", "F F F F", "1 1 1 4611686018427387904", 1) +
                  std::string(16, '\0'));
    EXPECT_TRUE(throws_input_error(
        [&] { read_point_cloud(path); },
        {path, "field 'w' has COUNT 4611686018427387904", "expected 1 to 65536"}));
    for (const char* encoding : {"binary", "ascii"}) {
        std::string header = binary_header("x y z normal_x normal_y normal_z", "4 4 4 4 4 4",
                                           "F F F F F F", "1 1 1 0 1 1", 1);
        header.replace(header.rfind("binary"), 6, encoding);
        test::write_file(path, header + std::string(20, '\0'));
        EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                       {path, "field 'normal_x' has COUNT 0"}));
    }
    // A field far out of a record's reach: offsets of 2^60 bytes used to wrap around.
    test::write_file(
        path, binary_header("pad x y z", "8 4 4 4", "F F F F", "1152921504606846976 1 1 1", 1) +
                  std::string(20, '\0'));
    EXPECT_TRUE(
        throws_input_error([&] { read_point_cloud(path); }, {path, "field 'pad' has COUNT"}));
    // A normal that is a vector of 3 is no normal: read without normals, not past its value.
    std::string vector_normals = binary_header("x y z normal_x normal_y normal_z", "4 4 4 4 4 4",
                                               "F F F F F F", "1 1 1 3 1 1", 1);
    for (float v : {1.f, 2.f, 3.f, 9.f, 9.f, 9.f, 0.f, 1.f}) put_bytes<float>(vector_normals, v);
    test::write_file(path, vector_normals);
    const PointCloud cloud = read_point_cloud(path);
    EXPECT_TRUE(at::equal(cloud.points, float_rows({1, 2, 3})));
    EXPECT_FALSE(cloud.has_normals());
}

TEST(IoPcd, UnsupportedAndMalformedFilesAreReported) {
    test::TempDir dir;
    const std::string path = dir.file("bad.pcd");
    std::string header = binary_header("x y z", "4 4 4", "F F F", "1 1 1", 2);
    const size_t data = header.rfind("DATA");
    test::write_file(path,
                     header.substr(0, data) + "DATA binary_compressed\n" + std::string(30, '\0'));
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 11", "binary_compressed PCD is not supported"}));
    const std::string ascii_header = header.substr(0, data) + "DATA ascii\n";
    test::write_file(path, ascii_header + "1.5 2.5 3.5\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 12", "ends after 1 of the 2 points"}));
    test::write_file(path, binary_header("x y z", "4 4 4", "F F F", "1 1 1", 2000000000) +
                               std::string(24, '\0'));
    EXPECT_TRUE(
        throws_input_error([&] { read_point_cloud(path); },
                           {path, "truncated binary PCD", "2000000000 points of 12 bytes"}));
    const size_t points = ascii_header.find("POINTS 2");
    test::write_file(
        path, ascii_header.substr(0, points) + "POINTS 2000000000\nDATA ascii\n" + "1 2 3\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "declares 2000000000 points", "6 bytes"}));
    test::write_file(path, ascii_header + "1 2 3\n4 5\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 13", "expected 3 values, found 2"}));
    test::write_file(path, ascii_header + "1 2 3\n4 5 six\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "line 13", "'six'"}));
    test::write_file(path, binary_header("x y z", "4 4", "F F F", "1 1 1", 1));
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "3 FIELDS but 2 SIZE"}));
    test::write_file(path,
                     binary_header("x y w", "4 4 4", "F F F", "1 1 1", 1) + std::string(12, '\0'));
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "no 'z' field"}));
    test::write_file(path, binary_header("x y z", "4 4 3", "F F F", "1 1 1", 1));
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "field 'z'", "TYPE F with SIZE 3"}));
    test::write_file(path, "VERSION 0.7\nFIELDS x y z\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "no DATA line"}));
}

TEST(IoPcd, OrganisedCloudsWithNanPointsNeedDropInvalid) {
    test::TempDir dir;
    const std::string path = dir.file("organised.pcd");
    test::write_file(path,
                     "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
                     "HEIGHT 2\nDATA ascii\n0 0 0\nnan nan nan\n1 1 1\nnan nan nan\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "2 of 4 points", "first is point 1"}));
    ReadOptions options;
    options.drop_invalid = true;
    EXPECT_TRUE(at::equal(read_point_cloud(path, options).points, float_rows({0, 0, 0, 1, 1, 1})));
}

}  // namespace
}  // namespace pumeta
