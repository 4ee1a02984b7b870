// The subcommands of the `pumeta` binary. Each add_*_command registers one subcommand and
// its callback on the app; main() wires them up and turns exceptions into exit codes.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "pumeta/geometry/io.h"

namespace pumeta::cli {

void add_info_command(CLI::App& app);
void add_convert_command(CLI::App& app);
void add_sample_command(CLI::App& app);
void add_metrics_command(CLI::App& app);
void add_gen_shapes_command(CLI::App& app);
void add_make_dataset_command(CLI::App& app);
void add_train_command(CLI::App& app);
void add_upsample_command(CLI::App& app);
/// command_line: the full invocation, recorded in eval summaries.
void add_eval_command(CLI::App& app, const std::string& command_line);
void add_meta_train_command(CLI::App& app);
/// The paper's tables (eval/reproduce.h).
void add_reproduce_command(CLI::App& app, const std::string& command_line);
void add_report_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_contact_sheet_command(CLI::App& app);
/// Where a model's error on held-out patches comes from (eval/diagnose.h).
void add_diagnose_command(CLI::App& app);
/// Paired intervals between two eval runs (eval/compare_runs.h).
void add_compare_command(CLI::App& app);
/// Released weights of other implementations as pumeta models (models/import.h).
void add_import_command(CLI::App& app);

/// The largest --ratio any command accepts.
inline constexpr int64_t kMaxRatio = 256;

/// Checks of numeric option values, each failing with one line that names the accepted range.
/// A number in [low, high] (NaN and infinities are refused).
CLI::Validator number_in(double low, double high);
/// A finite number greater than `low`.
CLI::Validator number_above(double low);
/// A whole number in [low, high].
CLI::Validator integer_in(int64_t low, int64_t high);
/// A whole number >= 0 that fits 64 bits (seeds).
CLI::Validator seed_value();

/// Options shared by commands that read geometry files: --format, --drop-invalid.
void add_read_options(CLI::App& command, ReadOptions& options);

/// The options of train and meta-train that shape a run: --config, --set, --resume,
/// --max-minutes, --allow-change.
struct RunArgs {
    std::string config;
    std::vector<std::string> overrides;
    bool resume = false;
    double max_minutes = 0;
    std::vector<std::string> allow_changes;
};
void add_run_options(CLI::App& command, RunArgs& args, const std::string& what);

/// --world-size, --rank, --master of train and meta-train.
struct DistributedArgs {
    int64_t world_size = 0;  // 0: not given
    int64_t rank = -1;       // -1: not given
    std::string master;
};
void add_distributed_options(CLI::App& command, DistributedArgs& args);
/// Fills config["distributed"]: environment first, then the flags that were given.
void apply_distributed_args(nlohmann::json& config, const DistributedArgs& args);

/// Prints a JSON value on stdout (one line) — the --json contract.
void print_json(const nlohmann::json& value);

}  // namespace pumeta::cli
