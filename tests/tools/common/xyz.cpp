// tools/common/xyz.h through each external baseline program that is built (pumeta-ear needs
// libcgal-dev, pumeta-mls libpcl-dev): bad input is exit code 2 with one line naming the file
// and no output file.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

class ExternalBaseline : public ::testing::TestWithParam<const char*> {};

TEST_P(ExternalBaseline, BadInputIsExitTwoWithOneLineNamingTheFile) {
    std::string program = test::built_program(GetParam());
    if (program.empty()) GTEST_SKIP() << GetParam() << " not built";
    test::TempDir dir;
    auto run = [&](const std::string& input) {
        return test::run_command(program, {dir.file(input), dir.file("out.xyz"), "--ratio", "4"});
    };
    test::write_file(dir.file("bad.xyz"), "1 2 3\nnot a point\n");
    test::CommandResult r = run("bad.xyz");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("bad.xyz: line 2"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out.xyz")));
    r = run("missing.xyz");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("missing.xyz: cannot open"), std::string::npos) << r.err;
    test::write_file(dir.file("few.xyz"), "0 0 0\n1 0 0\n");
    r = run("few.xyz");
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("few.xyz: 2 points"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out.xyz")));
}

INSTANTIATE_TEST_SUITE_P(Programs, ExternalBaseline, ::testing::Values("pumeta-ear", "pumeta-mls"));

}  // namespace
}  // namespace pumeta
