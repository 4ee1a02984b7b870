#include "pumeta/core/version.h"

#include <gtest/gtest.h>

#include <regex>

#include "support/test_util.h"

namespace pumeta {
namespace {

TEST(Version, NamesTheVersionCommitLibTorchAndBlas) {
    EXPECT_TRUE(std::regex_match(version(), std::regex(R"(\d+\.\d+\.\d+)"))) << version();
    EXPECT_TRUE(std::regex_match(git_commit(), std::regex(R"([0-9a-f]{12}(-dirty)?|unknown)")))
        << git_commit();
    EXPECT_EQ(torch_version().rfind("1.", 0), 0u) << torch_version();
    const nlohmann::json info = build_info();
    EXPECT_EQ(info["version"], version());
    EXPECT_EQ(info["commit"], git_commit());
    EXPECT_FALSE(info["blas"]["name"].get<std::string>().empty());
}

TEST(Version, TheCliPrintsItWithoutASubcommand) {
    const test::CommandResult r = test::run_cli({"--version"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out, build_info_text());
}

}  // namespace
}  // namespace pumeta
