#include "pumeta/eval/cases_csv.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>

#include "pumeta/core/error.h"

namespace pumeta {

namespace {

/// A field as csv_number() writes it: empty (NaN) or a whole-field floating-point value.
bool is_csv_number(const std::string& field) {
    if (field.empty()) return true;
    char* end = nullptr;
    std::strtod(field.c_str(), &end);
    return end == field.c_str() + field.size();
}

/// The fields of one line; getline drops a trailing empty field.
std::vector<std::string> split_fields(const std::string& line) {
    std::vector<std::string> fields;
    std::stringstream row(line);
    for (std::string field; std::getline(row, field, ',');) fields.push_back(field);
    return fields;
}

/// A score read back; a field that is not a number, or beyond double's range, is NaN.
double parse_score(const std::string& text) {
    if (text.empty()) return std::nan("");
    try {
        return std::stod(text);
    } catch (const std::exception&) {
        return std::nan("");
    }
}

}  // namespace

std::string csv_number(double v) { return std::isfinite(v) ? fmt::format("{:.9g}", v) : ""; }

double csv_value(const std::string& field) {
    return field.empty() ? std::nan("") : std::strtod(field.c_str(), nullptr);
}

void write_cases_csv_row(std::ostream& out, const std::vector<std::string>& row) {
    out << row[0];
    for (size_t f = 1; f < row.size(); ++f) out << "," << row[f];
    out << "\n" << std::flush;
}

std::map<std::string, std::vector<std::string>> read_finished_rows(const std::string& file) {
    std::map<std::string, std::vector<std::string>> rows;
    std::ifstream in(file);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    size_t start = text.find('\n');  // after the header
    if (text.compare(0, start, kCasesCsvHeader) != 0) return rows;
    while (start != std::string::npos && start + 1 < text.size()) {
        size_t end = text.find('\n', start + 1);
        if (end == std::string::npos) break;  // no newline: an unfinished row
        std::vector<std::string> fields = split_fields(text.substr(start + 1, end - start - 1));
        start = end;
        if (fields.empty() || fields.size() > kCasesCsvFields) continue;
        fields.resize(kCasesCsvFields);  // getline drops trailing empty fields
        if (std::all_of(fields.begin() + 1, fields.end(), is_csv_number)) rows[fields[0]] = fields;
    }
    return rows;
}

CaseScores read_cases_csv(const std::string& file) {
    CaseScores result;
    std::ifstream in(file);
    std::string line;
    if (!std::getline(in, line)) throw_input_error(file, "empty cases.csv");
    std::vector<std::string> header = split_fields(line);
    while (std::getline(in, line)) {
        std::vector<std::string> fields = split_fields(line);
        fields.resize(header.size());
        result.cases.push_back(fields[0]);
        for (size_t i = 1; i < header.size(); ++i)
            result.scores[header[i]].push_back(parse_score(fields[i]));
    }
    return result;
}

std::vector<std::string> first_case_names(const std::string& file, int64_t count) {
    std::ifstream in(file);
    std::string line;
    std::vector<std::string> names;
    std::getline(in, line);  // header
    while (static_cast<int64_t>(names.size()) < count && std::getline(in, line))
        names.push_back(line.substr(0, line.find(',')));
    return names;
}

}  // namespace pumeta
