// `pumeta report` on a quick miniature reproduction: the page holds the tables and figures,
// every image it links exists, and headless Chromium (Debian's `chromium`, installed by
// scripts/setup.sh) renders it with every image loaded.
#include "pumeta/eval/report.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <regex>

#include "pumeta/core/error.h"
#include "pumeta/eval/reproduce.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

class ReportTest : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        dir_ = new test::TempDir();
        nlohmann::json config = test::make_tiny_reproduction(dir_->path());
        reproduce(ReproduceConfig::from_json(config, "quick"), dir_->file("results"), "test");
        summary_ = write_report(dir_->file("results"), dir_->file("report"));
    }
    static void TearDownTestSuite() { delete dir_; }

    static std::vector<std::string> image_sources(const std::string& html) {
        std::vector<std::string> sources;
        std::regex img("<img src=\"([^\"]+)\"");
        for (auto it = std::sregex_iterator(html.begin(), html.end(), img);
             it != std::sregex_iterator(); ++it)
            sources.push_back((*it)[1]);
        return sources;
    }

    static test::TempDir* dir_;
    static ReportSummary summary_;
};
test::TempDir* ReportTest::dir_ = nullptr;
ReportSummary ReportTest::summary_;

TEST_F(ReportTest, PageHasTablesFiguresAndPlotsAndEveryLinkedImageExists) {
    std::string html = test::read_file(dir_->file("report/index.html"));
    EXPECT_NE(html.find("<h2>Table I:"), std::string::npos);
    EXPECT_NE(html.find("<h2>Table V:"), std::string::npos);
    EXPECT_GE(std::count(html.begin(), html.end(), '\n'), 20);
    EXPECT_NE(html.find("<table>"), std::string::npos);
    // One object figure per case of each set (2 sets, at most 2 cases each), three plots.
    EXPECT_GE(summary_.object_figures, 2);
    EXPECT_EQ(summary_.plots, 3);
    std::vector<std::string> sources = image_sources(html);
    EXPECT_EQ(static_cast<int>(sources.size()), summary_.object_figures + summary_.plots);
    for (const std::string& src : sources) {
        EXPECT_EQ(src.find("://"), std::string::npos) << "not self-contained: " << src;
        EXPECT_TRUE(fs::exists(dir_->path() / "report" / src)) << src;
    }
}

TEST_F(ReportTest, ChromiumRendersThePageWithEveryImageLoaded) {
    std::string chromium = test::find_program("chromium");
    if (chromium.empty()) GTEST_SKIP() << "chromium not installed (scripts/setup.sh installs it)";
    std::string url = "file://" + fs::absolute(dir_->path() / "report" / "index.html").string();
    std::vector<std::string> flags = {"--headless", "--no-sandbox", "--disable-gpu",
                                      "--virtual-time-budget=10000",
                                      "--user-data-dir=" + dir_->file("chromium-profile")};
    std::vector<std::string> dump = flags;
    dump.push_back("--dump-dom");
    dump.push_back(url);
    test::CommandResult dom = test::run_command(chromium, dump);
    ASSERT_EQ(dom.exit_code, 0) << dom.err;
    EXPECT_NE(dom.out.find("<table>"), std::string::npos);
    std::smatch match;
    ASSERT_TRUE(std::regex_search(dom.out, match, std::regex("images: all ([0-9]+) loaded")))
        << "image check did not pass: "
        << dom.out.substr(std::min(dom.out.size(), dom.out.find("image-check")), 300);
    EXPECT_EQ(std::stoi(match[1]), summary_.object_figures + summary_.plots);

    std::vector<std::string> shot = flags;
    std::string png = dir_->file("screenshot.png");
    shot.push_back("--screenshot=" + png);
    shot.push_back("--window-size=1280,2400");
    shot.push_back(url);
    test::CommandResult result = test::run_command(chromium, shot);
    ASSERT_EQ(result.exit_code, 0) << result.err;
    ASSERT_TRUE(fs::exists(png));
    EXPECT_GT(fs::file_size(png), 20000u) << "screenshot looks blank";
}

TEST(Report, AnythingButAReproduceOutputIsAnInputError) {
    test::TempDir dir;
    EXPECT_THROW(write_report(dir.path().string(), dir.file("report")), InputError);
    test::write_file(dir.file("tables.json"), "{\"tables\": 1}");
    EXPECT_THROW(write_report(dir.path().string(), dir.file("report")), InputError);
}

}  // namespace
}  // namespace pumeta
