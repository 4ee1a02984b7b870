#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iostream>

#include "pumeta/cli/commands.h"
#include "pumeta/distributed/process_group.h"

namespace pumeta::cli {

namespace {

// The whole of `text` as a double; false for anything else (trailing characters included).
bool parse_double(const std::string& text, double& value) {
    if (text.empty()) return false;
    char* end = nullptr;
    errno = 0;
    value = std::strtod(text.c_str(), &end);
    return end == text.c_str() + text.size() && errno != ERANGE;
}

bool parse_integer(const std::string& text, int64_t& value) {
    if (text.empty()) return false;
    char* end = nullptr;
    errno = 0;
    const long long parsed = std::strtoll(text.c_str(), &end, 10);
    value = parsed;
    return end == text.c_str() + text.size() && errno != ERANGE;
}

}  // namespace

CLI::Validator number_in(double low, double high) {
    return CLI::Validator(
        [low, high](std::string& text) -> std::string {
            double value;
            if (!parse_double(text, value) || !std::isfinite(value))
                return fmt::format("expected a finite number, found '{}'", text);
            if (value < low || value > high)
                return fmt::format("expected a number from {} to {}, found {}", low, high, text);
            return {};
        },
        fmt::format("NUMBER in [{}, {}]", low, high));
}

CLI::Validator number_above(double low) {
    return CLI::Validator(
        [low](std::string& text) -> std::string {
            double value;
            if (!parse_double(text, value) || !std::isfinite(value))
                return fmt::format("expected a finite number, found '{}'", text);
            if (!(value > low))
                return fmt::format("expected a number greater than {}, found {}", low, text);
            return {};
        },
        fmt::format("NUMBER > {}", low));
}

CLI::Validator integer_in(int64_t low, int64_t high) {
    return CLI::Validator(
        [low, high](std::string& text) -> std::string {
            int64_t value;
            if (!parse_integer(text, value))
                return fmt::format("expected a whole number, found '{}'", text);
            if (value < low || value > high)
                return fmt::format("expected a whole number from {} to {}, found {}", low, high,
                                   text);
            return {};
        },
        fmt::format("INT in [{}, {}]", low, high));
}

CLI::Validator seed_value() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            char* end = nullptr;
            errno = 0;
            if (text.empty() || text[0] == '-' || text[0] == '+' ||
                (std::strtoull(text.c_str(), &end, 10), end != text.c_str() + text.size()) ||
                errno == ERANGE)
                return fmt::format("expected a whole number from 0 to 2^64-1, found '{}'", text);
            return {};
        },
        "SEED");
}

void add_read_options(CLI::App& command, ReadOptions& options) {
    command.add_option("--format", options.format,
                       "input format, overriding the extension (ply, xyz, off, obj, stl, pcd, "
                       "las)");
    command.add_flag("--drop-invalid", options.drop_invalid,
                     "drop points with NaN or infinite coordinates instead of failing");
}

void add_run_options(CLI::App& command, RunArgs& args, const std::string& what) {
    command.add_option("--config", args.config, what + " config JSON")->required();
    command.add_option("--set", args.overrides, "override a config field: key=value");
    command.add_flag("--resume", args.resume, "continue the run in run_dir from state.ckpt");
    command
        .add_option("--max-minutes", args.max_minutes,
                    "checkpoint and stop after this many minutes (0 = no limit)")
        ->check(number_in(0, 1e7));
    command.add_option("--allow-change", args.allow_changes,
                       "with --resume: a config field (e.g. steps) allowed to differ from the "
                       "run's; repeatable");
}

void add_distributed_options(CLI::App& command, DistributedArgs& args) {
    command
        .add_option("--world-size", args.world_size,
                    "processes of a distributed run (default: $WORLD_SIZE, else 1)")
        ->check(integer_in(1, 65536));
    command.add_option("--rank", args.rank, "this process's rank (default: $RANK)")
        ->check(integer_in(0, 65535));
    command.add_option("--master", args.master,
                       "HOST:PORT where rank 0 serves the rendezvous (default: "
                       "$MASTER_ADDR:$MASTER_PORT)");
}

void apply_distributed_args(nlohmann::json& config, const DistributedArgs& args) {
    apply_distributed_environment(config["distributed"]);
    if (args.world_size > 0) config["distributed"]["world_size"] = args.world_size;
    if (args.rank >= 0) config["distributed"]["rank"] = args.rank;
    if (!args.master.empty()) config["distributed"]["master"] = args.master;
}

void print_json(const nlohmann::json& value) { std::cout << value.dump() << std::endl; }

}  // namespace pumeta::cli
