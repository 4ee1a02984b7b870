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

TEST(IoObj, MeshRoundTrips) {
    test::TempDir dir;
    const TriangleMesh mesh{uniform_random_points(40, 8),
                            (at::arange(180, at::kLong) * 11 % 40).view({60, 3})};
    write_mesh(dir.file("m.obj"), mesh);
    const TriangleMesh back = read_mesh(dir.file("m.obj"));
    EXPECT_TRUE(at::equal(back.vertices, mesh.vertices));
    EXPECT_TRUE(at::equal(back.faces, mesh.faces));
}

TEST(IoObj, NegativeAndSlashIndicesAndPolygons) {
    const Geometry geometry = read_geometry(test::io_fixture("negative_indices.obj"));
    EXPECT_TRUE(at::equal(geometry.cloud.points,
                          float_rows({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0, 0, 2, 1, 0})));
    // f -4 -3 -2 -1 after four vertices; f 2 5 6 3; f 5 6 -6 after six vertices.
    EXPECT_TRUE(
        at::equal(geometry.faces, index_rows({0, 1, 2, 0, 2, 3, 1, 4, 5, 1, 5, 2, 4, 5, 0})));
}

TEST(IoObj, VerticesWithoutFacesAreACloud) {
    test::TempDir dir;
    const std::string path = dir.file("c.obj");
    test::write_file(path, "v 1 2 3 0.5 0.5 0.5\nv 4 5 6\nvn 0 0 1\n");
    const Geometry geometry = read_geometry(path);
    EXPECT_FALSE(geometry.faces.defined());
    EXPECT_TRUE(at::equal(geometry.cloud.points, float_rows({1, 2, 3, 4, 5, 6})));
}

TEST(IoObj, BadIndicesAndTokensAreReportedWithLines) {
    test::TempDir dir;
    const std::string path = dir.file("bad.obj");
    const std::string square = "v 0 0 0\nv 1 0 0\nv 1 1 0\n";
    test::write_file(path, square + "f 1 2 4\n");
    EXPECT_TRUE(throws_input_error(
        [&] { read_mesh(path); },
        {path, "line 4", "vertex index 4 out of range", "3 vertices defined so far"}));
    test::write_file(path, square + "f 0 1 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); }, {path, "line 4", "vertex index 0"}));
    test::write_file(path, square + "f -1 -2 -4\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); }, {path, "line 4", "vertex index -4"}));
    test::write_file(path, square + "f 1\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 4", "at least 3 vertices, found 1"}));
    // A two-vertex face is an edge: skipped (with a warning), the triangles around it kept.
    test::write_file(path, square + "f 1 2\nf 1 2 3\n");
    EXPECT_EQ(read_mesh(path).num_faces(), 1);
    test::write_file(path, square + "f 1 a/1 3\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 4", "expected a vertex index", "'a'"}));
    test::write_file(path, "v 0 0\n");
    EXPECT_TRUE(throws_input_error([&] { read_mesh(path); },
                                   {path, "line 1", "needs 3 coordinates, found 2"}));
}

}  // namespace
}  // namespace pumeta
