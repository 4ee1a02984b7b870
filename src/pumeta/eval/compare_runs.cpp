#include "pumeta/eval/compare_runs.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <map>

#include "pumeta/core/error.h"
#include "pumeta/eval/cases_csv.h"

namespace pumeta {
namespace {

CaseScores read_run(const std::string& dir) {
    const std::string file = (std::filesystem::path(dir) / kCasesCsvFile).string();
    if (!std::filesystem::is_regular_file(file))
        throw_input_error(dir, "no {} (not the output directory of a finished `pumeta eval`)",
                          kCasesCsvFile);
    return read_cases_csv(file);
}

/// The column's value per case name (cases without the column are absent).
std::map<std::string, double> by_case(const CaseScores& run, const std::string& column) {
    std::map<std::string, double> values;
    auto it = run.scores.find(column);
    if (it == run.scores.end()) return values;
    for (size_t i = 0; i < run.cases.size() && i < it->second.size(); ++i)
        values[run.cases[i]] = it->second[i];
    return values;
}

}  // namespace

RunComparison compare_runs(const std::string& base_dir, const std::string& method_dir,
                           int64_t resamples, uint64_t seed) {
    RunComparison c;
    c.base_dir = base_dir;
    c.method_dir = method_dir;
    CaseScores base = read_run(base_dir), method = read_run(method_dir);
    std::map<std::string, bool> in_method;
    for (const std::string& name : method.cases) in_method[name] = true;
    std::map<std::string, bool> in_base;
    for (const std::string& name : base.cases) {
        in_base[name] = true;
        (in_method.count(name) ? c.shared_cases : c.only_in_base) += 1;
    }
    for (const std::string& name : method.cases) c.only_in_method += in_base.count(name) ? 0 : 1;
    if (c.shared_cases == 0)
        throw_input_error(method_dir, "no case in common with {} (different sets or ratios?)",
                          base_dir);

    for (const char* metric : {"cd", "hd", "p2f", "psnr"}) {
        std::map<std::string, double> b = by_case(base, metric), m = by_case(method, metric);
        std::vector<double> base_values, method_values;
        for (const auto& [name, value] : b) {
            auto other = m.find(name);
            if (other == m.end()) continue;
            base_values.push_back(value);
            method_values.push_back(other->second);
        }
        MetricComparison mc;
        mc.metric = metric;
        mc.higher_is_better = std::string(metric) == "psnr";
        mc.paired =
            compare_paired(base_values, method_values, mc.higher_is_better, resamples, seed);
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
