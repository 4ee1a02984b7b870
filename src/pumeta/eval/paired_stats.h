// Paired comparison of two methods scored on the same cases: mean difference, relative change
// and a percentile-bootstrap 95 % interval of the mean paired difference (resampling cases).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <vector>

namespace pumeta {

struct PairedComparison {
    int64_t count = 0;
    double mean_base = 0, mean_method = 0;
    double mean_difference = 0;  ///< mean(method − base)
    double relative_change = 0;  ///< mean_difference / mean_base
    double ci_low = 0, ci_high = 0;
    /// Fraction of cases where the method is better than the base (lower, or higher when
    /// higher_is_better).
    double fraction_improved = 0;
    bool excludes_zero() const { return ci_low > 0 || ci_high < 0; }
};

/// base[i] and method[i] are the same case's scores; pairs with a non-finite value are
/// dropped. Same inputs and seed, same interval. Throws InputError on length mismatch.
PairedComparison compare_paired(const std::vector<double>& base, const std::vector<double>& method,
                                bool higher_is_better = false, int64_t resamples = 2000,
                                uint64_t seed = 1);

/// The comparison as JSON (count, mean_difference, relative_change, ci95, excludes_zero,
/// fraction_improved): reproduce's tables.json and `pumeta compare --json`.
nlohmann::json paired_json(const PairedComparison& c);

}  // namespace pumeta
