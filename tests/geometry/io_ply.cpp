#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "geometry/io_test_util.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::float_rows;
using test::index_rows;
using test::put_bytes;
using test::throws_input_error;

PointCloud random_cloud(int64_t n, uint64_t seed) {
    PointCloud cloud;
    cloud.points = uniform_random_points(n, seed);
    cloud.normals = uniform_random_points(n, seed + 1);
    cloud.colors = (at::arange(3 * n, at::kLong) * 37 % 256).to(at::kByte).view({n, 3});
    return cloud;
}

void expect_equal_clouds(const PointCloud& a, const PointCloud& b) {
    EXPECT_TRUE(at::equal(a.points, b.points));
    ASSERT_EQ(a.has_normals(), b.has_normals());
    ASSERT_EQ(a.has_colors(), b.has_colors());
    if (a.has_normals()) {
        EXPECT_TRUE(at::equal(a.normals, b.normals));
    }
    if (a.has_colors()) {
        EXPECT_TRUE(at::equal(a.colors, b.colors));
    }
}

TEST(IoPly, CloudRoundTripsBitExactlyInBinaryAndAscii) {
    test::TempDir dir;
    const PointCloud cloud = random_cloud(500, 7);
    for (bool binary : {true, false}) {
        const std::string path = dir.file(binary ? "binary.ply" : "ascii.ply");
        write_point_cloud(path, cloud, {"", binary});
        const std::string text = test::read_file(path);
        EXPECT_NE(text.find(binary ? "format binary_little_endian" : "format ascii"),
                  std::string::npos);
        expect_equal_clouds(read_point_cloud(path), cloud);
    }
    // Points only: the single-memcpy path of both writer and reader.
    const std::string path = dir.file("points.ply");
    write_point_cloud(path, PointCloud{cloud.points, {}, {}});
    const PointCloud back = read_point_cloud(path);
    EXPECT_TRUE(at::equal(back.points, cloud.points));
    EXPECT_FALSE(back.has_normals());
    EXPECT_FALSE(back.has_colors());
}

TEST(IoPly, MeshRoundTripsInBinaryAndAscii) {
    test::TempDir dir;
    const TriangleMesh mesh{float_rows({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0.5f}),
                            index_rows({0, 1, 2, 0, 2, 3, 3, 2, 1})};
    for (bool binary : {true, false}) {
        const std::string path = dir.file("mesh.ply");
        write_mesh(path, mesh, {"", binary});
        const TriangleMesh back = read_mesh(path);
        EXPECT_TRUE(at::equal(back.vertices, mesh.vertices));
        EXPECT_TRUE(at::equal(back.faces, mesh.faces));
    }
}

// A binary PLY exercising every scalar type (both names of each), an element between vertex
// and face with a fixed layout, and faces whose list has a non-default count/index type and
// a scalar before it.
std::string typed_binary_ply(bool big_endian) {
    std::string out = "ply\n";
    out += big_endian ? "format binary_big_endian 1.0\n" : "format binary_little_endian 1.0\n";
    out +=
        "comment every scalar type\n"
        "element vertex 4\n"
        "property char c\nproperty double x\nproperty uint8 u8\nproperty float32 y\n"
        "property short s\nproperty int16 z\nproperty ushort us\nproperty int i\n"
        "property uint ui\nproperty int8 i8\nproperty float nx\nproperty float64 ny\n"
        "property int32 nz\nproperty uchar red\nproperty uint16 green\nproperty float blue\n"
        "element edge 2\nproperty int vertex1\nproperty uint32 vertex2\n"
        "element face 2\nproperty uchar flags\nproperty list ushort uint vertex_indices\n"
        "end_header\n";
    const double xs[4] = {0.5, -1.25, 1e6, 3};
    const float ys[4] = {2, -3.5f, 0.125f, 7};
    const int16_t zs[4] = {-7, 100, 3000, -32768};
    for (int v = 0; v < 4; ++v) {
        put_bytes<int8_t>(out, -5, big_endian);
        put_bytes<double>(out, xs[v], big_endian);
        put_bytes<uint8_t>(out, 200, big_endian);
        put_bytes<float>(out, ys[v], big_endian);
        put_bytes<int16_t>(out, -300, big_endian);
        put_bytes<int16_t>(out, zs[v], big_endian);
        put_bytes<uint16_t>(out, 60000, big_endian);
        put_bytes<int32_t>(out, -100000, big_endian);
        put_bytes<uint32_t>(out, 4000000000u, big_endian);
        put_bytes<int8_t>(out, 9, big_endian);
        put_bytes<float>(out, 1.f, big_endian);
        put_bytes<double>(out, 0.5, big_endian);
        put_bytes<int32_t>(out, -2, big_endian);
        put_bytes<uint8_t>(out, static_cast<uint8_t>(10 * v), big_endian);
        put_bytes<uint16_t>(out, 300, big_endian);  // clamped to 255
        put_bytes<float>(out, 0.5f, big_endian);    // float colour in [0,1]: 128
    }
    for (int e = 0; e < 2; ++e) {
        put_bytes<int32_t>(out, 99, big_endian);
        put_bytes<uint32_t>(out, 98, big_endian);
    }
    put_bytes<uint8_t>(out, 1, big_endian);
    put_bytes<uint16_t>(out, 3, big_endian);
    for (uint32_t index : {0u, 1u, 2u}) put_bytes<uint32_t>(out, index, big_endian);
    put_bytes<uint8_t>(out, 1, big_endian);
    put_bytes<uint16_t>(out, 4, big_endian);
    for (uint32_t index : {0u, 1u, 2u, 3u}) put_bytes<uint32_t>(out, index, big_endian);
    return out;
}

TEST(IoPly, ReadsEveryScalarTypeInBothByteOrders) {
    test::TempDir dir;
    for (bool big_endian : {true, false}) {
        const std::string path = dir.file(big_endian ? "big.ply" : "little.ply");
        test::write_file(path, typed_binary_ply(big_endian));
        const Geometry geometry = read_geometry(path);
        EXPECT_TRUE(at::equal(
            geometry.cloud.points,
            float_rows({0.5f, 2, -7, -1.25f, -3.5f, 100, 1e6f, 0.125f, 3000, 3, 7, -32768})))
            << geometry.cloud.points;
        ASSERT_TRUE(geometry.cloud.has_normals());
        EXPECT_TRUE(at::equal(geometry.cloud.normals,
                              float_rows({1, 0.5f, -2}).expand({4, 3}).contiguous()));
        ASSERT_TRUE(geometry.cloud.has_colors());
        EXPECT_TRUE(
            at::equal(geometry.cloud.colors,
                      at::tensor({0, 255, 128, 10, 255, 128, 20, 255, 128, 30, 255, 128}, at::kByte)
                          .view({4, 3})));
        EXPECT_TRUE(at::equal(geometry.faces, index_rows({0, 1, 2, 0, 1, 2, 0, 2, 3})));
    }
}

TEST(IoPly, SkipsExtraPropertiesAndElementsAndTriangulatesPolygons) {
    const Geometry geometry = read_geometry(test::io_fixture("mixed_polygons.ply"));
    EXPECT_TRUE(at::equal(geometry.cloud.points, float_rows({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0,
                                                             0.5f, 1.5f, 0, 0.5f, -0.5f, 0})));
    EXPECT_FALSE(geometry.cloud.has_normals());
    EXPECT_TRUE(at::equal(
        geometry.cloud.colors,
        at::tensor({255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30, 40, 50, 60, 70, 80, 90}, at::kByte)
            .view({6, 3})));
    // Triangle, quad (2 triangles) and pentagon (3), fan-triangulated from their first corner.
    EXPECT_TRUE(at::equal(geometry.faces,
                          index_rows({0, 1, 2, 0, 1, 2, 0, 2, 3, 0, 5, 1, 0, 1, 2, 0, 2, 4})));
}

TEST(IoPly, BinaryVertexElementWithListIsWalkedRowByRow) {
    test::TempDir dir;
    std::string bytes =
        "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
        "property list uchar int ring\nproperty float y\nproperty float z\nend_header\n";
    put_bytes<float>(bytes, 1);
    put_bytes<uint8_t>(bytes, 2);
    put_bytes<int32_t>(bytes, 5);
    put_bytes<int32_t>(bytes, 6);
    put_bytes<float>(bytes, 2);
    put_bytes<float>(bytes, 3);
    put_bytes<float>(bytes, 4);
    put_bytes<uint8_t>(bytes, 0);
    put_bytes<float>(bytes, 5);
    put_bytes<float>(bytes, 6);
    const std::string path = dir.file("ring.ply");
    test::write_file(path, bytes);
    EXPECT_TRUE(at::equal(read_point_cloud(path).points, float_rows({1, 2, 3, 4, 5, 6})));
    // One byte short: the walk names the row and the byte offset.
    test::write_file(path, bytes.substr(0, bytes.size() - 1));
    EXPECT_TRUE(throws_input_error(
        [&] { read_point_cloud(path); },
        {path, "truncated", "element 'vertex' row 1", "needs 4 bytes", "found 3"}));
}

std::string binary_cloud_header(const std::string& count) {
    return "ply\nformat binary_little_endian 1.0\nelement vertex " + count +
           "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
}

TEST(IoPly, TruncatedBinaryNamesElementOffsetAndSizes) {
    test::TempDir dir;
    const std::string path = dir.file("truncated.ply");
    const std::string header = binary_cloud_header("100");
    test::write_file(path, header + std::string(1190, '\0'));
    EXPECT_TRUE(throws_input_error(
        [&] { read_point_cloud(path); },
        {path, "truncated binary PLY", "element 'vertex'", "100 rows of 12 bytes", "1200 bytes",
         "byte offset " + std::to_string(header.size()), "only 1190 bytes remain"}));

    // A complete vertex block followed by a cut face list.
    std::string mesh =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n";
    mesh += std::string(36, '\0');
    put_bytes<uint8_t>(mesh, 3);
    put_bytes<int32_t>(mesh, 0);
    test::write_file(path, mesh);
    EXPECT_TRUE(throws_input_error(
        [&] { read_geometry(path); },
        {path, "truncated", "element 'face' row 0", "needs 12 bytes", "found 4"}));
}

TEST(IoPly, HugeDeclaredCountsAreRejectedBeforeAllocation) {
    test::TempDir dir;
    const std::string path = dir.file("huge.ply");
    test::write_file(path, binary_cloud_header("4000000000000000000") + std::string(24, '\0'));
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "truncated", "'vertex'", "4000000000000000000 rows"}));
    test::write_file(path,
                     "ply\nformat ascii 1.0\nelement vertex 900000000000\nproperty float x\n"
                     "property float y\nproperty float z\nend_header\n0 0 0\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "declares 900000000000 'vertex' rows"}));
}

// Found by fuzzing: the up-front size check assumes empty lists, so a list element before a
// list-free one moved the reader past what that check had covered.
TEST(IoPly, ListElementBeforeVerticesIsBoundedByTheBuffer) {
    test::TempDir dir;
    const std::string path = dir.file("faces-first.ply");
    const std::string header =
        "ply\nformat binary_little_endian 1.0\nelement face 1\n"
        "property list uchar int vertex_indices\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nend_header\n";
    std::string bytes = header;
    put_bytes<uint8_t>(bytes, 3);
    for (int32_t i : {0, 1, 2}) put_bytes<int32_t>(bytes, i);
    for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put_bytes<float>(bytes, v);
    test::write_file(path, bytes);
    // Complete: faces first is legal.
    const Geometry mesh = read_geometry(path);
    EXPECT_TRUE(at::equal(mesh.faces, index_rows({0, 1, 2})));
    EXPECT_TRUE(at::equal(mesh.cloud.points, float_rows({0, 0, 0, 1, 0, 0, 0, 1, 0})));
    // The vertex block short by the list's 12 bytes, which the up-front check cannot see.
    test::write_file(path, bytes.substr(0, bytes.size() - 12));
    EXPECT_TRUE(throws_input_error([&] { read_geometry(path); },
                                   {path, "truncated binary PLY", "element 'vertex'",
                                    "3 rows of 12 bytes", "only 24 bytes remain"}));
    // A skipped list-free element after a list element (the skip used to land past the end).
    std::string skipped = header;
    skipped.insert(skipped.find("end_header"), "element extra 2\nproperty double w\n");
    std::string body = bytes.substr(header.size());
    test::write_file(path, skipped + body + std::string(8, '\0'));
    EXPECT_TRUE(throws_input_error([&] { read_geometry(path); },
                                   {path, "truncated binary PLY", "element 'extra'",
                                    "2 rows of 8 bytes", "only 8 bytes remain"}));
}

// Found by fuzzing: a binary element with zero rows copied from a null pointer.
TEST(IoPly, EmptyBinaryVertexElementIsAnEmptyFile) {
    test::TempDir dir;
    const std::string path = dir.file("none.ply");
    test::write_file(path, binary_cloud_header("0"));
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "no points"}));
}

TEST(IoPly, AsciiFileShorterThanItsHeaderGivesTheLine) {
    test::TempDir dir;
    const std::string path = dir.file("short.ply");
    std::string text =
        "ply\nformat ascii 1.0\nelement vertex 10\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n";
    for (int i = 0; i < 8; ++i) text += "0.25 0.5 0.75\n";  // lines 8..15
    test::write_file(path, text);
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 15", "after 8 of the 10 'vertex' rows"}));
}

TEST(IoPly, BadTokensMissingValuesAndHeaderErrorsAreReported) {
    test::TempDir dir;
    const std::string path = dir.file("bad.ply");
    const std::string header =
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n";
    test::write_file(path, header + "0 0 0\n1 abc 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 9", "expected a number", "'abc'"}));
    test::write_file(path, header + "0 0 0\n1 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 9", "no value for property 'z'"}));
    test::write_file(path, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n0 0 0\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "no 'end_header'"}));
    test::write_file(path, "ply\nelement vertex 1\nproperty float x\nend_header\n0\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "no 'format' line"}));
    test::write_file(path, "ply\nformat binary_middle_endian 1.0\nend_header\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 2", "unknown PLY format 'binary_middle_endian'"}));
    test::write_file(path,
                     "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 4", "unknown PLY property type 'quad'"}));
    test::write_file(path,
                     "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                     "property float y\nend_header\n1 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "lacks an x, y or z"}));
    test::write_file(path, "solid cube\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "not a PLY file"}));
}

TEST(IoPly, FaceIndicesOutOfRangeNameTheFace) {
    test::TempDir dir;
    const std::string path = dir.file("faces.ply");
    test::write_file(path,
                     "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
                     "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 7\n");
    EXPECT_TRUE(throws_input_error(
        [&] { read_mesh(path); },
        {path, "line 14 (face 1)", "vertex index 7 out of range", "3 vertices"}));

    std::string bytes =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n";
    bytes += std::string(36, '\0');
    put_bytes<uint8_t>(bytes, 3);
    for (int32_t index : {0, -1, 2}) put_bytes<int32_t>(bytes, index);
    test::write_file(path, bytes);
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "face 0", "vertex index -1 out of range"}));

    test::write_file(path,
                     "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                     "end_header\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 13 (face 0)", "at least 3 vertices, found 2"}));
}

}  // namespace
}  // namespace pumeta
