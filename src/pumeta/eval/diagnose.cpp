#include "pumeta/eval/diagnose.h"

#include <ATen/ATen.h>

#include <cmath>
#include <map>

#include "pumeta/core/error.h"

namespace pumeta {

nlohmann::json diagnose_patches(const Backbone& model, const ValidationSet& set, int64_t batch) {
    if (batch < 1) throw_input_error("diagnose", "batch must be >= 1");
    const int64_t n = set.input.size(0);
    std::map<std::string, std::pair<double, int64_t>> sums;  // field -> (sum, count)
    for (int64_t start = 0; start < n; start += batch) {
        const int64_t end = std::min(n, start + batch);
        nlohmann::json fields =
            model.diagnose(set.input.slice(0, start, end), set.gt.slice(0, start, end));
        if (!fields.is_object()) continue;
        for (const auto& [name, values] : fields.items())
            for (const auto& v : values) {
                const double x = v.is_number() ? v.get<double>() : std::nan("");
                if (!std::isfinite(x)) continue;
                sums[name].first += x;
                ++sums[name].second;
            }
    }
    nlohmann::json out = {
        {"patches", n}, {"cd", validation_cd(model, set)}, {"input_cd", set.input_cd}};
    for (const auto& [name, sum] : sums)
        out[name] = sum.second > 0 ? nlohmann::json(sum.first / sum.second) : nlohmann::json();
    return out;
}

}  // namespace pumeta
