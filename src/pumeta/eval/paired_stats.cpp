#include "pumeta/eval/paired_stats.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "pumeta/core/error.h"

namespace pumeta {

PairedComparison compare_paired(const std::vector<double>& base, const std::vector<double>& method,
                                bool higher_is_better, int64_t resamples, uint64_t seed) {
    if (base.size() != method.size())
        throw_input_error("compare_paired", "{} base scores but {} method scores", base.size(),
                          method.size());
    if (resamples < 1) throw_input_error("compare_paired", "resamples must be positive");
    std::vector<double> differences;
    PairedComparison c;
    int64_t improved = 0;
    for (size_t i = 0; i < base.size(); ++i) {
        if (!std::isfinite(base[i]) || !std::isfinite(method[i])) continue;
        differences.push_back(method[i] - base[i]);
        c.mean_base += base[i];
        c.mean_method += method[i];
        improved += higher_is_better ? method[i] > base[i] : method[i] < base[i];
    }
    c.count = static_cast<int64_t>(differences.size());
    if (c.count == 0) return c;
    const double n = static_cast<double>(c.count);
    c.mean_base /= n;
    c.mean_method /= n;
    c.mean_difference = c.mean_method - c.mean_base;
    c.relative_change = c.mean_base != 0 ? c.mean_difference / c.mean_base : std::nan("");
    c.fraction_improved = improved / n;

    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<size_t> pick(0, differences.size() - 1);
    std::vector<double> means(static_cast<size_t>(resamples));
    for (double& mean : means) {
        double sum = 0;
        for (size_t i = 0; i < differences.size(); ++i) sum += differences[pick(rng)];
        mean = sum / n;
    }
    std::sort(means.begin(), means.end());
    auto quantile = [&](double q) {
        auto index = static_cast<size_t>(std::llround(q * static_cast<double>(resamples - 1)));
        return means[std::min(index, means.size() - 1)];
    };
    c.ci_low = quantile(0.025);
    c.ci_high = quantile(0.975);
    return c;
}

nlohmann::json paired_json(const PairedComparison& c) {
    return {{"count", c.count},
            {"mean_difference", c.mean_difference},
            {"relative_change", c.relative_change},
            {"ci95", {c.ci_low, c.ci_high}},
            {"excludes_zero", c.excludes_zero()},
            {"fraction_improved", c.fraction_improved}};
}

}  // namespace pumeta
