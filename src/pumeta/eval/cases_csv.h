// cases.csv: the per-case scores of one `pumeta eval` run (evaluate_cases writes it row by row;
// reproduce and report read it). A header line, then one row per case: its name and numbers,
// an empty field standing for NaN (a score that does not apply, e.g. P2F without a mesh).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <ostream>
#include <string>
#include <vector>

namespace pumeta {

/// The file name in a run's output directory; cases.csv.tmp while the run is unfinished.
inline constexpr const char* kCasesCsvFile = "cases.csv";
inline constexpr const char* kCasesCsvTmpFile = "cases.csv.tmp";

/// The header line that evaluate_cases writes (without its newline).
inline constexpr const char* kCasesCsvHeader =
    "case,n_in,n_out,cd,hd,p2f,psnr,seconds,tta_seconds,loss_before,loss_after";
inline constexpr size_t kCasesCsvFields = 11;

/// A number as a field: 9 significant digits, or empty for NaN and infinities.
std::string csv_number(double v);

/// A field as csv_number() writes it back as a number (empty = NaN).
double csv_value(const std::string& field);

/// Writes one row and flushes: an interrupted run resumes after it (read_finished_rows).
void write_cases_csv_row(std::ostream& out, const std::vector<std::string>& row);

/// The complete rows of an interrupted run's cases.csv.tmp (a last line cut short by the
/// interruption, or any row that does not parse, is dropped and so evaluated again): case
/// name -> the row's kCasesCsvFields fields. Empty when the header is not kCasesCsvHeader.
std::map<std::string, std::vector<std::string>> read_finished_rows(const std::string& file);

/// A cases.csv read back: the cases in file order and, per column of its header, one value per
/// case (NaN for an empty or unparsable field).
struct CaseScores {
    std::vector<std::string> cases;
    std::map<std::string, std::vector<double>> scores;  // column -> per case
};

/// InputError when the file is empty or missing.
CaseScores read_cases_csv(const std::string& file);

/// The names of the first `count` cases (fewer when the file has fewer; none when it is
/// missing).
std::vector<std::string> first_case_names(const std::string& file, int64_t count);

}  // namespace pumeta
