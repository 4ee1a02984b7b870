// pumeta-mls (tools/mls, built only when PCL is installed): PCL's moving least squares
// upsampling on a sampled sphere gives about r·N points on the sphere; bad input is exit
// code 2 with no output file.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "pumeta/geometry/io.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

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

TEST(PumetaMls, BadInputIsExitTwoWithOneLineNamingTheFile) {
    std::string mls = mls_program();
    if (mls.empty()) GTEST_SKIP() << "pumeta-mls not built (needs libpcl-dev)";
    test::TempDir dir;
    test::write_file(dir.file("bad.xyz"), "1 2 3\nnot a point\n");
    test::CommandResult r =
        test::run_command(mls, {dir.file("bad.xyz"), dir.file("out.xyz"), "--ratio", "4"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("bad.xyz: line 2"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out.xyz")));
    r = test::run_command(mls, {dir.file("missing.xyz"), dir.file("out.xyz"), "--ratio", "4"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("missing.xyz: cannot open"), std::string::npos) << r.err;
    test::write_file(dir.file("few.xyz"), "0 0 0\n1 0 0\n");
    r = test::run_command(mls, {dir.file("few.xyz"), dir.file("out.xyz"), "--ratio", "4"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("few.xyz: 2 points"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out.xyz")));
}

}  // namespace
}  // namespace pumeta
