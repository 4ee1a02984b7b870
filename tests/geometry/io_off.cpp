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
using test::throws_input_error;

TEST(IoOff, MeshAndCloudRoundTrip) {
    test::TempDir dir;
    const TriangleMesh mesh{uniform_random_points(50, 5),
                            (at::arange(240, at::kLong) * 7 % 50).view({80, 3})};
    write_mesh(dir.file("m.off"), mesh);
    const TriangleMesh back = read_mesh(dir.file("m.off"));
    EXPECT_TRUE(at::equal(back.vertices, mesh.vertices));
    EXPECT_TRUE(at::equal(back.faces, mesh.faces));

    const at::Tensor points = uniform_random_points(20, 6);
    write_point_cloud(dir.file("c.off"), {points, {}, {}});
    const Geometry cloud = read_geometry(dir.file("c.off"));
    EXPECT_TRUE(at::equal(cloud.cloud.points, points));
    EXPECT_FALSE(cloud.is_mesh());
}

TEST(IoOff, CommentsColoursAndPolygonsOfAnySize) {
    const Geometry geometry = read_geometry(test::io_fixture("polygons.off"));
    EXPECT_TRUE(at::equal(geometry.cloud.points,
                          float_rows({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5f, 1.5f, 0})));
    EXPECT_FALSE(geometry.cloud.has_colors());
    // 1 + 2 + 3 triangles from the triangle, quad and pentagon.
    EXPECT_TRUE(at::equal(geometry.faces,
                          index_rows({0, 1, 2, 0, 1, 2, 0, 2, 3, 0, 1, 2, 0, 2, 4, 0, 4, 3})));
}

TEST(IoOff, NoffNormalsAndCountsOnTheHeaderLine) {
    test::TempDir dir;
    const std::string path = dir.file("n.off");
    test::write_file(path, "NOFF 3 1 0\n0 0 0 0 0 1\n1 0 0 0 1 0\n0 1 0 1 0 0\n3 2 1 0\n");
    const Geometry geometry = read_geometry(path);
    EXPECT_TRUE(at::equal(geometry.cloud.normals, float_rows({0, 0, 1, 0, 1, 0, 1, 0, 0})));
    EXPECT_TRUE(at::equal(geometry.faces, index_rows({2, 1, 0})));
}

TEST(IoOff, MalformedFilesAreReportedWithLines) {
    test::TempDir dir;
    const std::string path = dir.file("bad.off");
    test::write_file(path, "PLY\n3 1 0\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 1", "expected an OFF header", "'PLY'"}));
    test::write_file(path, "OFF\n4 1 0\n0.5 0.5 0.5\n1.5 0.5 0.5\n0.5 1.5 0.5\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 5", "ends after 3 of 4 vertices"}));
    test::write_file(path, "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); }, {path, "ends after 1 of 2 faces"}));
    test::write_file(path, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 6", "declares 4 vertices, found 3"}));
    test::write_file(path, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 3 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 6 (face 0)", "vertex index 3 out of range"}));
    test::write_file(path, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 zero\n3 0 1 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 5", "expected a coordinate", "'zero'"}));
    test::write_file(path, "OFF\n99999999999 1 0\n0 0 0\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 2", "declares 99999999999 vertices"}));
    test::write_file(path, "OFF BINARY\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); }, {path, "binary OFF"}));
}

}  // namespace
}  // namespace pumeta
