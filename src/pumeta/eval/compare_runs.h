// Paired comparison of two `pumeta eval` runs on the same cases (`pumeta compare`): for each
// metric, the mean of each run over the cases both scored and the bootstrap interval of the
// mean per-case difference, so "is B better than A on these objects?" has an answer with its
// uncertainty, not two means side by side.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "pumeta/eval/paired_stats.h"

namespace pumeta {

struct MetricComparison {
    std::string metric;  ///< a cases.csv column: cd, hd, p2f, psnr
    bool higher_is_better = false;
    PairedComparison paired;
};

struct RunComparison {
    std::string base_dir, method_dir;
    int64_t shared_cases = 0;    ///< cases present in both runs
    int64_t only_in_base = 0;    ///< cases the method run lacks
    int64_t only_in_method = 0;  ///< cases the base run lacks
    std::vector<MetricComparison> metrics;
};

/// Reads DIR/cases.csv of both runs, pairs rows by case name and compares cd, hd, p2f and psnr
/// (PSNR higher is better). A metric neither run scored on any shared case (P2F without
/// meshes) is left out. InputError naming the file when a run has no cases.csv, and when the
/// runs share no case.
RunComparison compare_runs(const std::string& base_dir, const std::string& method_dir,
                           int64_t resamples = 2000, uint64_t seed = 1);

/// One line per metric: both means, the relative change, the interval and the share of cases
/// improved; a marker where the interval excludes zero.
std::string format_run_comparison(const RunComparison& c);

}  // namespace pumeta
