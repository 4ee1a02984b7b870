// The options of the commands that run a model (upsample, eval): which model and ratio, and
// the user's overrides of the model's adaptation defaults.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <optional>
#include <string>

#include "pumeta/inference/model_file.h"
#include "pumeta/inference/upsample.h"

namespace pumeta::cli {

struct ModelArgs {
    std::string model;  // empty: the shipped model for the ratio
    int64_t ratio = 0;  // 0: not given
    uint64_t seed = 0;
    std::optional<int64_t> tta_steps;
    std::optional<double> tta_lr;
    std::string tta_unit;  // empty: the default (object); "oracle" is eval's diagnostic
    std::string tta_downsampler;
    std::string tta_optimizer;
    int64_t batch_patches = 0;              // the backbone's
    std::optional<double> spacing_bound;    // the pipeline's default
    std::optional<int64_t> whole_cloud;     // the backbone's choice; 0: patches
    std::string keep_input = "auto";        // on, off, auto
    std::optional<double> line_projection;  // automatic
    std::string select = "auto";            // fps, ownership, auto
    std::string device = "cpu";
};

/// --model, --ratio, --seed, --tta-*, --batch-patches, --spacing-bound, --device. `oracle_unit`:
/// whether
/// --tta-unit accepts "oracle" (eval).
void add_model_options(CLI::App& command, ModelArgs& args, bool oracle_unit);

/// The model that serves the output ratio (serve(): --model, else the shipped one for the
/// ratio; `ratio` 0 = the model's), moved to --device.
ServedModel load_model(const ModelArgs& args, int64_t ratio);

/// The pipeline's options for `served`: its ratio, the seed and batch size, and the model's
/// adaptation with the user's overrides (adaptation_for()).
UpsampleOptions upsample_options(const ModelArgs& args, const ServedModel& served);

}  // namespace pumeta::cli
