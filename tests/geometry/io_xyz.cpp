#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "geometry/io_test_util.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::float_rows;
using test::throws_input_error;

TEST(IoXyz, RoundTripsPointsAndNormalsBitExactly) {
    test::TempDir dir;
    PointCloud cloud{uniform_random_points(300, 11), uniform_random_points(300, 12), {}};
    // Values whose shortest decimal forms are long or use exponents.
    cloud.points[0][0] = 1e-30f;
    cloud.points[0][1] = -3.4028235e38f;
    cloud.points[0][2] = 0.1f;
    for (const char* name : {"c.xyz", "c.txt", "c.pts"}) {
        write_point_cloud(dir.file(name), cloud);
        const PointCloud back = read_point_cloud(dir.file(name));
        EXPECT_TRUE(at::equal(back.points, cloud.points)) << name;
        ASSERT_TRUE(back.has_normals());
        EXPECT_TRUE(at::equal(back.normals, cloud.normals));
    }
    write_point_cloud(dir.file("p.xyz"), {cloud.points, {}, {}});
    const PointCloud back = read_point_cloud(dir.file("p.xyz"));
    EXPECT_TRUE(at::equal(back.points, cloud.points));
    EXPECT_FALSE(back.has_normals());
}

TEST(IoXyz, ReadsCountHeaderCommentsBlankLinesAndPlusSigns) {
    const PointCloud cloud = read_point_cloud(test::io_fixture("count_header.xyz"));
    EXPECT_TRUE(at::equal(cloud.points, float_rows({0, 0, 0, 1.5f, -2, 300, 4, 5, 6})));
    EXPECT_FALSE(cloud.has_normals());
}

TEST(IoXyz, SixCommaSeparatedColumnsAreXyzAndNormals) {
    const PointCloud cloud = read_point_cloud(test::io_fixture("comma_normals.txt"));
    EXPECT_TRUE(at::equal(cloud.points, float_rows({0.5f, 1, 2, -1, 0.25f, 8})));
    EXPECT_TRUE(at::equal(cloud.normals, float_rows({0, 0, 1, 1, 0, 0})));
}

TEST(IoXyz, MalformedLinesGiveTheirLineNumber) {
    test::TempDir dir;
    const std::string path = dir.file("bad.xyz");
    test::write_file(path, "0 0 0\n1 1 1\n2 x2 2\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 3", "expected a coordinate", "'x2'"}));
    test::write_file(path, "0 0 0 1\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 1", "3 columns", "6", "found 4"}));
    test::write_file(path, "0 0 0\n\n1 1 1 0 0 1\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 3", "expected 3 columns", "found 6"}));
    test::write_file(path, "5\n0 0 0\n1 1 1\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 1", "declares 5 points", "has 2"}));
    test::write_file(path, "three\n0 0 0\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); },
                                   {path, "line 1", "expected a point count", "'three'"}));
    // Binary junk is shown as '?' so that the message stays one printable line.
    test::write_file(path, "0 0 \x01\n");
    EXPECT_TRUE(throws_input_error([&] { read_point_cloud(path); }, {path, "line 1", "found '?'"}));
}

}  // namespace
}  // namespace pumeta
