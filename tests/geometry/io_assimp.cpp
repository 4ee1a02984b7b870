// Third-party files from Debian's assimp-testmodels: real exporters' output must load, and the
// package's malformed files must give InputError, never a crash or a huge allocation.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "geometry/io_test_util.h"
#include "pumeta/geometry/io.h"

namespace pumeta {
namespace {

using test::assimp_model;
using test::throws_input_error;

class IoAssimp : public ::testing::Test {
  protected:
    void SetUp() override {
        if (test::assimp_dir().empty())
            GTEST_SKIP() << "assimp-testmodels is missing (scripts/setup.sh installs it)";
    }
};

TEST_F(IoAssimp, ValidFilesOfEveryMeshFormatLoad) {
    struct Expected {
        const char* file;
        int64_t vertices;
        int64_t triangles;
    };
    // Counts after merging STL corners and triangulating quads; the cubes are 6 quads.
    for (const Expected& e : std::vector<Expected>{
             {"PLY/cube.ply", 8, 12},         // float32/uint8 aliases, vertex_index
             {"PLY/cube_binary.ply", 8, 12},  // binary little endian
             {"PLY/Wuson.ply", 11184, 3732},  // header text without 'comment'
             {"OFF/Cube.off", 8, 12},
             {"OFF/Wuson.off", 3205, 3732},
             {"OBJ/box.obj", 8, 12},
             {"OBJ/spider.obj", 762, 1368},
             {"OBJ/box_without_lineending.obj", 8, 12},
             {"STL/Spider_ascii.stl", 722, 1368},
             {"STL/Spider_binary.stl", 722, 1368},
             {"STL/3DSMaxExport.STL", 1042, 2000},  // upper-case extension
             {"STL/triangle_with_two_solids.stl", 6, 2},
         }) {
        const TriangleMesh mesh = read_mesh(assimp_model(e.file));
        EXPECT_EQ(mesh.num_vertices(), e.vertices) << e.file;
        EXPECT_EQ(mesh.num_faces(), e.triangles) << e.file;
    }
    // The same spider as ascii and binary STL gives the same indexed mesh.
    const TriangleMesh ascii = read_mesh(assimp_model("STL/Spider_ascii.stl"));
    const TriangleMesh binary = read_mesh(assimp_model("STL/Spider_binary.stl"));
    EXPECT_TRUE(at::allclose(ascii.vertices, binary.vertices, 1e-5, 1e-5));
    EXPECT_TRUE(at::equal(ascii.faces, binary.faces));
}

TEST_F(IoAssimp, PlyAttributesAreCarried) {
    const PointCloud points = read_point_cloud(assimp_model("PLY/points.ply"));
    ASSERT_TRUE(points.has_normals() && points.has_colors());
    EXPECT_TRUE(at::equal(points.colors[1], at::tensor({255, 0, 255}, at::kInt).to(at::kByte)));
    EXPECT_TRUE(at::equal(points.normals[2], at::tensor({1.f, 0.f, 0.f})));
    // Colours stored as floats in [0,1].
    const PointCloud floats = read_point_cloud(assimp_model("PLY/float-color.ply"));
    EXPECT_TRUE(at::equal(floats.colors[0], at::tensor({0, 0, 255}, at::kInt).to(at::kByte)));
}

TEST_F(IoAssimp, MalformedFilesThrowInputError) {
    struct Expected {
        const char* file;
        const char* problem;
    };
    for (const Expected& e : std::vector<Expected>{
             {"invalid/empty.ply", "file is empty"},
             {"invalid/empty.obj", "file is empty"},
             {"invalid/empty.off", "file is empty"},
             {"invalid/OutOfMemory.off", "declares 353535235358 vertices"},
             {"invalid/malformed.obj", "line 23: vertex index 12 out of range"},
             {"invalid/malformed2.obj", "line 23: a face needs at least 3 vertices, found 0"},
             {"OFF/invalid.off", "line 6 (face 0): a polygon needs at least 3 vertices, found 0"},
             {"OBJ/box_UTF16BE.obj", "UTF-16"},
             {"OBJ/number_formats.obj", "line 11: expected a coordinate, found '3.1+e2'"},
             // Declares a vertex list property that its rows do not hold.
             {"PLY/issue623.ply", "line 13: 'vertex' row has no value for property"},
             // Cut 69 bytes short of its 70051 declared vertices.
             {"PLY/pond.0.ply", "element 'vertex' declares 70051 rows of 31 bytes"},
         }) {
        const std::string path = assimp_model(e.file);
        EXPECT_TRUE(throws_input_error([&] { read_geometry(path); }, {path, e.problem}));
    }
}

}  // namespace
}  // namespace pumeta
