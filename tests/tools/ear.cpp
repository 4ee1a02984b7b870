// pumeta-ear (tools/ear, built only when CGAL is installed): CGAL's edge-aware upsampling
// on a sampled sphere gives about r·N points on the sphere; bad input:
// tests/tools/common/xyz.cpp.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

std::string ear_program() { return test::built_program("pumeta-ear"); }

TEST(PumetaEar, UpsamplesASphereFourTimesOntoTheSphere) {
    std::string ear = ear_program();
    if (ear.empty()) GTEST_SKIP() << "pumeta-ear not built (needs libcgal-dev)";
    test::TempDir dir;
    at::Tensor points = uniform_random_points(2048, 4);
    points = points / points.norm(2, 1, true);
    write_point_cloud(dir.file("in.xyz"), {points});
    test::CommandResult r =
        test::run_command(ear, {dir.file("in.xyz"), dir.file("out.xyz"), "--ratio", "4"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    at::Tensor out = read_point_cloud(dir.file("out.xyz")).points;
    EXPECT_NEAR(out.size(0), 8192, 0.02 * 8192);
    double off_sphere = (out.norm(2, 1) - 1).abs().mean().item<double>();
    EXPECT_LT(off_sphere, 0.01);
}

}  // namespace
}  // namespace pumeta
