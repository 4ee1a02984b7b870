#include "pumeta/eval/compare_runs.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <utility>

#include "pumeta/core/error.h"
#include "pumeta/eval/cases_csv.h"
#include "pumeta/eval/tables.h"

namespace pumeta {
namespace {

CaseScores read_run(const std::string& dir) {
    const std::string file = (std::filesystem::path(dir) / kCasesCsvFile).string();
    if (!std::filesystem::is_regular_file(file))
        throw_input_error(dir, "no {} (not the output directory of a finished `pumeta eval`)",
                          kCasesCsvFile);
    return read_cases_csv(file);
}

}  // namespace

RunComparison compare_runs(const std::string& base_dir, const std::string& method_dir,
                           int64_t resamples, uint64_t seed) {
    RunComparison c;
    c.base_dir = base_dir;
    c.method_dir = method_dir;
    CaseScores base = read_run(base_dir), method = read_run(method_dir);
    std::map<std::string, size_t> method_row;
    for (size_t i = 0; i < method.cases.size(); ++i) method_row[method.cases[i]] = i;
    std::vector<std::pair<size_t, size_t>> pairs;  // (base row, method row) of a shared case
    for (size_t i = 0; i < base.cases.size(); ++i) {
        auto it = method_row.find(base.cases[i]);
        if (it == method_row.end())
            ++c.only_in_base;
        else
            pairs.emplace_back(i, it->second);
    }
    c.shared_cases = static_cast<int64_t>(pairs.size());
    c.only_in_method = static_cast<int64_t>(method_row.size() - pairs.size());
    if (c.shared_cases == 0)
        throw_input_error(method_dir, "no case in common with {} (different sets or ratios?)",
                          base_dir);

    // The test-set metrics (`eval --cases`), then the published protocol's (`eval --benchmark`,
    // ×10³, all lower-is-better); a run has one kind or the other.
    std::vector<std::pair<std::string, bool>> columns;
    for (const Metric* metric : {&kCd, &kHd, &kP2f, &kPsnr})
        columns.emplace_back(metric->column, metric->higher_is_better);
    for (const char* column : {"cd_1e3", "hd_1e3", "hd_legacy_1e3", "p2f_1e3"})
        columns.emplace_back(column, false);
    for (const auto& [column, higher_is_better] : columns) {
        auto b = base.scores.find(column), m = method.scores.find(column);
        if (b == base.scores.end() || m == method.scores.end()) continue;
        std::vector<double> base_values, method_values;
        for (auto [i, j] : pairs) {
            base_values.push_back(b->second[i]);
            method_values.push_back(m->second[j]);
        }
        MetricComparison mc{
            column, higher_is_better,
            compare_paired(base_values, method_values, higher_is_better, resamples, seed)};
        if (mc.paired.count > 0) c.metrics.push_back(mc);
    }
    return c;
}

std::string format_run_comparison(const RunComparison& c) {
    std::string out = fmt::format("base   {}\nmethod {}\n{} cases in both", c.base_dir,
                                  c.method_dir, c.shared_cases);
    if (c.only_in_base || c.only_in_method)
        out += fmt::format(" ({} only in the base, {} only in the method: left out)",
                           c.only_in_base, c.only_in_method);
    out += "\n";
    for (const MetricComparison& m : c.metrics) {
        const PairedComparison& p = m.paired;
        out += fmt::format(
            "{:<5} base {:.6g}  method {:.6g}  change {:+.2f} %  difference {:+.4g} "
            "(95 % CI [{:+.4g}, {:+.4g}]){}  better on {:.0f} % of {} cases\n",
            m.metric, p.mean_base, p.mean_method, 100 * p.relative_change, p.mean_difference,
            p.ci_low, p.ci_high, p.excludes_zero() ? " *" : "", 100 * p.fraction_improved, p.count);
    }
    out += "* the interval excludes zero\n";
    return out;
}

}  // namespace pumeta
