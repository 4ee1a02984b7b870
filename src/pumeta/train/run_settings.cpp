#include "pumeta/train/run_settings.h"

#include <algorithm>
#include <cmath>

#include "pumeta/core/error.h"
#include "pumeta/data/patch_set.h"

namespace pumeta {

double LrSchedule::at(int64_t step) const {
    return std::max(lr * std::pow(rate, static_cast<double>(step) / static_cast<double>(steps)),
                    floor);
}

void check_schedule(const LrSchedule& s, const std::string& context, const char* lr,
                    const char* steps) {
    if (!(s.lr > 0)) throw_input_error(context, "'{}' must be positive", lr);
    if (s.steps < 1) throw_input_error(context, "'{}' must be >= 1", steps);
}

Hdf5PatchKeys hdf5_patch_keys(const RunSettings& s) { return {s.data_input_key, s.data_gt_key}; }

void check_run_settings(const RunSettings& s, const std::string& context,
                        const std::string& batch_name, int64_t batch) {
    for (const auto& [key, value] : {std::pair{"train_data", &s.train_data},
                                     {"run_dir", &s.run_dir},
                                     {"data_input_key", &s.data_input_key},
                                     {"data_gt_key", &s.data_gt_key}})
        if (value->empty()) throw_input_error(context, "'{}' is required", key);
    if (s.steps < 0) throw_input_error(context, "'steps' must be >= 0");
    if (s.log_every < 1 || s.val_every < 1 || s.checkpoint_every < 1)
        throw_input_error(context, "log_every, val_every and checkpoint_every must be >= 1");
    if (batch < 1) throw_input_error(context, "{} < 1", batch_name);
    if (batch % s.distributed.world_size != 0)
        throw_input_error(context, "{} {} does not split evenly over {} processes", batch_name,
                          batch, s.distributed.world_size);
    parse_input_sampler(s.sampler);
}

}  // namespace pumeta
