#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "geometry/io_test_util.h"
#include "pumeta/geometry/io.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::float_rows;
using test::index_rows;
using test::put_bytes;
using test::throws_input_error;

// The unit square of square.stl as an indexed mesh: shared corners merged (also -0 and 0).
const std::vector<float> kSquareVertices = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
const std::vector<int64_t> kSquareFaces = {0, 1, 2, 0, 2, 3};

// A binary STL of the same square whose 80-byte header starts with "solid", as many
// exporters write it.
std::string binary_square(uint32_t declared_triangles) {
    std::string header = "solid square written as binary";
    header.resize(80, ' ');
    std::string out = header;
    put_bytes<uint32_t>(out, declared_triangles);
    const float corners[2][3][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}},
                                    {{-0.f, 0, 0}, {1, 1, 0}, {0, 1, 0}}};
    for (const auto& triangle : corners) {
        for (float n : {0.f, 0.f, 1.f}) put_bytes<float>(out, n);
        for (const auto& corner : triangle)
            for (float c : corner) put_bytes<float>(out, c);
        put_bytes<uint16_t>(out, 0);
    }
    return out;
}

TEST(IoStl, AsciiCornersAreMergedIntoAnIndexedMesh) {
    const TriangleMesh mesh = read_mesh(test::io_fixture("square.stl"));
    EXPECT_TRUE(at::equal(mesh.vertices, float_rows(kSquareVertices)));
    EXPECT_TRUE(at::equal(mesh.faces, index_rows(kSquareFaces)));
}

TEST(IoStl, BinaryIsDetectedBySizeEvenWithASolidHeader) {
    test::TempDir dir;
    const std::string path = dir.file("square.stl");
    test::write_file(path, binary_square(2));
    const TriangleMesh mesh = read_mesh(path);
    EXPECT_TRUE(at::equal(mesh.vertices, float_rows(kSquareVertices)));
    EXPECT_TRUE(at::equal(mesh.faces, index_rows(kSquareFaces)));
}

TEST(IoStl, BinaryWithAWrongSizeIsReported) {
    test::TempDir dir;
    const std::string path = dir.file("short.stl");
    std::string bytes = binary_square(3);
    test::write_file(path, bytes);
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "declares 3 triangles (234 bytes)", "has 184 bytes"}));
    bytes[0] = 'S';  // no "solid": binary is the only reading
    test::write_file(path, bytes);
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); }, {path, "declares 3 triangles"}));
    test::write_file(path, "STL?");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); }, {path, "not an STL file"}));
}

TEST(IoStl, MalformedAsciiIsReportedWithLines) {
    test::TempDir dir;
    const std::string path = dir.file("bad.stl");
    const std::string begin = "solid t\nfacet normal 0 0 1\nouter loop\n";
    test::write_file(path, begin + "vertex 0 0 0\nvertex 1 0 0\nvertex 1 q 0\nendloop\nendfacet\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 6", "expected a coordinate", "'q'"}));
    test::write_file(path, begin + "vertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 7", "needs 3 vertices, found 2"}));
    test::write_file(path, begin + "vertex 0 0 0\nvertex 1 0 0\n");
    EXPECT_TRUE(
        throws_input_error([&] { read_mesh(path); }, {path, "ends inside the facet of line 2"}));
    test::write_file(path, begin + "vertex 0 0 0 1\n");
    EXPECT_TRUE(
        throws_input_error([&] { read_mesh(path); }, {path, "line 4", "expected 'vertex x y z'"}));
    test::write_file(path, "solid t\nfacet normal 0 0 1\nloop outer\n");
    EXPECT_TRUE(
        throws_input_error([&] { read_mesh(path); }, {path, "line 3", "unexpected 'loop'"}));
    test::write_file(path, "solid empty\nendsolid empty\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); }, {path, "no triangles"}));
}

}  // namespace
}  // namespace pumeta
