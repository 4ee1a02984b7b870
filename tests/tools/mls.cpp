// pumeta-mls (tools/mls, built only when PCL is installed): PCL's moving least squares
// upsampling on a sampled sphere gives about r·N points on the sphere; bad input:
// tests/tools/common/xyz.cpp.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>

#include "pumeta/geometry/io.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

std::string mls_program() { return test::built_program("pumeta-mls"); }

TEST(PumetaMls, UpsamplesASphereFourTimesOntoTheSphere) {
    std::string mls = mls_program();
    if (mls.empty()) GTEST_SKIP() << "pumeta-mls not built (needs libpcl-dev)";
    test::TempDir dir;
    at::Tensor points = uniform_random_points(2048, 4);
    points = points / points.norm(2, 1, true);
    write_point_cloud(dir.file("in.xyz"), {points});
    test::CommandResult r =
        test::run_command(mls, {dir.file("in.xyz"), dir.file("out.xyz"), "--ratio", "4"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    at::Tensor out = read_point_cloud(dir.file("out.xyz")).points;
    // Exactly r·N unless PCL produced fewer.
    EXPECT_LE(out.size(0), 8192);
    EXPECT_GT(out.size(0), 0.9 * 8192);
    double off_sphere = (out.norm(2, 1) - 1).abs().mean().item<double>();
    EXPECT_LT(off_sphere, 0.01);
    // Spread over the sphere, not piled on the inputs: every input has outputs nearby.
    EXPECT_LT(std::sqrt(knn(out, points, 1).sq_distances.max().item<double>()), 0.1);
}

}  // namespace
}  // namespace pumeta
