// compare_runs: rows pair by case name (not by order), cases only one run scored are counted
// and left out, P2F without meshes is dropped, PSNR counts higher as better, and the CLI turns
// a missing run into a one-line error.
#include "pumeta/eval/compare_runs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "pumeta/core/error.h"
#include "pumeta/eval/cases_csv.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

struct Row {
    std::string name;
    double cd, psnr, p2f;
};

std::string write_run(const test::TempDir& dir, const std::string& name,
                      const std::vector<Row>& rows) {
    std::filesystem::path run = dir.path() / name;
    std::filesystem::create_directories(run);
    std::ofstream out(run / kCasesCsvFile);
    out << kCasesCsvHeader << "\n";
    for (const Row& r : rows)
        write_cases_csv_row(
            out, {r.name, "100", "400", csv_number(r.cd), csv_number(0.1), csv_number(r.p2f),
                  csv_number(r.psnr), csv_number(1), "", "", ""});
    return run.string();
}

const MetricComparison* find_metric(const RunComparison& c, const std::string& metric) {
    for (const MetricComparison& m : c.metrics)
        if (m.metric == metric) return &m;
    return nullptr;
}

TEST(CompareRuns, PairsByCaseNameAndCountsTheCasesOnlyOneRunHas) {
    test::TempDir dir;
    const double nan = std::nan("");
    std::string base = write_run(dir, "base",
                                 {{"a", 1.0, 40, nan},
                                  {"b", 2.0, 41, nan},
                                  {"c", 3.0, 42, nan},
                                  {"only-base", 100.0, 10, nan}});
    // Other order, one case missing from the base, every shared case 10 % lower in CD.
    std::string method = write_run(
        dir, "method",
        {{"c", 2.7, 43, nan}, {"extra", 9.0, 1, nan}, {"a", 0.9, 41, nan}, {"b", 1.8, 42, nan}});
    RunComparison c = compare_runs(base, method, 500, 3);
    EXPECT_EQ(c.shared_cases, 3);
    EXPECT_EQ(c.only_in_base, 1);
    EXPECT_EQ(c.only_in_method, 1);
    const MetricComparison* cd = find_metric(c, "cd");
    ASSERT_NE(cd, nullptr);
    EXPECT_EQ(cd->paired.count, 3);
    EXPECT_NEAR(cd->paired.mean_base, 2.0, 1e-9);
    EXPECT_NEAR(cd->paired.mean_method, 1.8, 1e-9);
    EXPECT_NEAR(cd->paired.relative_change, -0.1, 1e-9);
    EXPECT_DOUBLE_EQ(cd->paired.fraction_improved, 1.0);
    EXPECT_LT(cd->paired.ci_high, 0.0);  // every difference negative: so is the interval
    // PSNR one dB higher on every case: better, higher being better.
    const MetricComparison* psnr = find_metric(c, "psnr");
    ASSERT_NE(psnr, nullptr);
    EXPECT_TRUE(psnr->higher_is_better);
    EXPECT_NEAR(psnr->paired.mean_difference, 1.0, 1e-9);
    EXPECT_DOUBLE_EQ(psnr->paired.fraction_improved, 1.0);
    // No P2F anywhere (no meshes): no P2F line.
    EXPECT_EQ(find_metric(c, "p2f"), nullptr);
    std::string text = format_run_comparison(c);
    EXPECT_NE(text.find("3 cases in both (1 only in the base, 1 only in the method"),
              std::string::npos)
        << text;
    EXPECT_NE(text.find("change -10.00 %"), std::string::npos) << text;
}

// `eval --benchmark` runs (the published protocol's columns, objects by name) compare too.
TEST(CompareRuns, BenchmarkRunsCompareOnTheProtocolsColumns) {
    test::TempDir dir;
    auto write = [&](const std::string& name, double scale) {
        std::filesystem::path run = dir.path() / name;
        std::filesystem::create_directories(run);
        std::ofstream out(run / kCasesCsvFile);
        out << "object,n_in,n_out,n_gt,cd_1e3,hd_1e3,hd_legacy_1e3,p2f_1e3,p2f_std_1e3,seconds\n";
        for (const auto& [object, cd] : {std::pair{"camel", 0.2}, {"star", 0.4}})
            out << object << ",2048,8192,8192," << cd * scale << ",30,2," << 1.5 * scale
                << ",1,2\n";
        return run.string();
    };
    const RunComparison c = compare_runs(write("plain", 1.0), write("adapted", 0.9), 200, 1);
    EXPECT_EQ(c.shared_cases, 2);
    const MetricComparison* cd = find_metric(c, "cd_1e3");
    ASSERT_NE(cd, nullptr);
    EXPECT_FALSE(cd->higher_is_better);
    EXPECT_NEAR(cd->paired.relative_change, -0.1, 1e-9);
    EXPECT_DOUBLE_EQ(cd->paired.fraction_improved, 1.0);
    ASSERT_NE(find_metric(c, "p2f_1e3"), nullptr);
    EXPECT_EQ(find_metric(c, "cd"), nullptr);
}

TEST(CompareRuns, MissingRunsAndDisjointRunsAreInputErrors) {
    test::TempDir dir;
    std::string base = write_run(dir, "base", {{"a", 1.0, 40, 0.1}});
    std::string other = write_run(dir, "other", {{"z", 1.0, 40, 0.1}});
    EXPECT_THROW(compare_runs(base, dir.file("absent")), InputError);
    EXPECT_THROW(compare_runs(base, other), InputError);

    test::CommandResult r = test::run_cli({"compare", base, dir.file("absent")});
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.err.find("absent: no cases.csv"), std::string::npos) << r.err;
    r = test::run_cli({"compare", base, base, "--json"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j.at("shared_cases"), 1);
    EXPECT_EQ(j.at("metrics").at("cd").at("mean_difference"), 0.0);
}

}  // namespace
}  // namespace pumeta
