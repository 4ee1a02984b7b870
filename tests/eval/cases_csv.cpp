// cases.csv: what evaluate_cases writes reads back as the same scores, an interrupted file
// yields only its complete rows, and the readers' edge cases (missing file, short rows).
#include "pumeta/eval/cases_csv.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "pumeta/core/error.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

std::vector<std::string> row(const std::string& name, double cd, double p2f) {
    return {name,
            "128",
            "512",
            csv_number(cd),
            csv_number(0.5),
            csv_number(p2f),
            csv_number(30),
            csv_number(0.25),
            "",
            csv_number(1e-3),
            csv_number(5e-4)};
}

TEST(CasesCsv, WrittenRowsReadBackAsTheSameScores) {
    test::TempDir dir;
    const std::string file = dir.file(kCasesCsvFile);
    {
        std::ofstream out(file);
        out << kCasesCsvHeader << "\n";
        write_cases_csv_row(out, row("chair", 1.25e-4, 3e-3));
        write_cases_csv_row(out, row("bunny", 2.5e-4, std::nan("")));  // no mesh: no P2F
    }
    CaseScores read = read_cases_csv(file);
    ASSERT_EQ(read.cases, (std::vector<std::string>{"chair", "bunny"}));
    EXPECT_EQ(read.scores.size(), kCasesCsvFields - 1);
    EXPECT_DOUBLE_EQ(read.scores.at("cd")[0], 1.25e-4);
    EXPECT_DOUBLE_EQ(read.scores.at("cd")[1], 2.5e-4);
    EXPECT_DOUBLE_EQ(read.scores.at("p2f")[0], 3e-3);
    EXPECT_TRUE(std::isnan(read.scores.at("p2f")[1]));
    EXPECT_TRUE(std::isnan(read.scores.at("tta_seconds")[0]));
    EXPECT_EQ(read.scores.at("n_out")[1], 512);

    EXPECT_EQ(first_case_names(file, 1), (std::vector<std::string>{"chair"}));
    EXPECT_EQ(first_case_names(file, 5).size(), 2u);
    EXPECT_TRUE(first_case_names(dir.file("absent.csv"), 5).empty());
    EXPECT_THROW(read_cases_csv(dir.file("absent.csv")), InputError);
}

TEST(CasesCsv, NumbersRoundTripAndNanIsAnEmptyField) {
    // 9 significant digits: a score comes back within its last digit.
    for (double v : {0.0, 1.0 / 3, 1e-12, 123456.789, -2.5})
        EXPECT_NEAR(csv_value(csv_number(v)), v, 1e-8 * std::abs(v)) << csv_number(v);
    EXPECT_EQ(csv_number(std::nan("")), "");
    EXPECT_EQ(csv_number(INFINITY), "");
    EXPECT_TRUE(std::isnan(csv_value("")));
}

TEST(CasesCsv, AnInterruptedFileKeepsOnlyItsCompleteRows) {
    test::TempDir dir;
    const std::string file = dir.file(kCasesCsvTmpFile);
    std::ostringstream text;
    text << kCasesCsvHeader << "\n";
    write_cases_csv_row(text, row("a", 1e-4, 1e-3));
    text << "b,128,512,not-a-number,,,,,,,\n";  // does not parse: evaluated again
    text << "c,128,512,1e-4,,,,,,,,,,,,\n";     // too many fields
    write_cases_csv_row(text, row("d", 2e-4, 1e-3));
    text << "e,128,5";  // cut short by the interruption
    test::write_file(file, text.str());
    auto rows = read_finished_rows(file);
    ASSERT_EQ(rows.size(), 2u);
    EXPECT_EQ(rows.at("a"), row("a", 1e-4, 1e-3));
    EXPECT_EQ(rows.at("d").size(), kCasesCsvFields);

    test::write_file(file, "case,other\na,1\n");  // another header: nothing to resume
    EXPECT_TRUE(read_finished_rows(file).empty());
}

}  // namespace
}  // namespace pumeta
