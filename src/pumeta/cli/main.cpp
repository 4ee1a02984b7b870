// pumeta: point-cloud upsampling with test-time adaptation. Exit codes: 0 success, 2 bad input
// or usage, 1 internal failure, 130 training stopped by Ctrl-C / SIGTERM after checkpointing.
#include <ATen/Parallel.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "pumeta/cli/commands.h"
#include "pumeta/core/allocator.h"
#include "pumeta/core/device.h"
#include "pumeta/core/error.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/core/version.h"

int main(int argc, char** argv) {
    pumeta::keep_freed_memory();
    CLI::App app{
        "pumeta: upsample sparse point clouds with neural networks adapted to each "
        "input by meta-learning"};
    app.require_subcommand(1);
    app.set_version_flag(
        "--version",
        [] {
            std::string text = pumeta::build_info_text();
            text.pop_back();  // CLI11 adds the last newline
            return text;
        },
        "print the version, the commit, LibTorch's version and the BLAS in use, and exit");
    int threads = 0;
    std::string log_level = "info";
    app.add_option("--threads", threads,
                   "CPU threads (default: all cores): training, metrics and the geometry of "
                   "upsampling (patches, kNN, FPS) use them all; upsampling runs batches of "
                   "patches (and per-patch adaptation) concurrently, each on one thread, so "
                   "the output has the same bytes on any count; one-θ' adaptation and "
                   "whole-cloud networks (PU-Dense, Grad-PU, PU-Gaussian) run on one")
        ->check(pumeta::cli::integer_in(1, 1024));
    app.add_option("--log-level", log_level, "trace, debug, info, warn, error or off")
        ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));
    app.parse_complete_callback([&] {
        // Logs and progress go to stderr; stdout carries results (--json, tables).
        spdlog::set_default_logger(spdlog::stderr_color_mt("pumeta"));
        spdlog::set_level(spdlog::level::from_str(log_level));
        spdlog::set_pattern("%^[%l]%$ %v");
        if (threads > 0) at::set_num_threads(threads);
    });

    pumeta::cli::add_info_command(app);
    pumeta::cli::add_convert_command(app);
    pumeta::cli::add_sample_command(app);
    pumeta::cli::add_metrics_command(app);
    pumeta::cli::add_gen_shapes_command(app);
    pumeta::cli::add_make_dataset_command(app);
    pumeta::cli::add_train_command(app);
    pumeta::cli::add_meta_train_command(app);
    pumeta::cli::add_upsample_command(app);
    pumeta::cli::add_render_command(app);
    pumeta::cli::add_contact_sheet_command(app);
    pumeta::cli::add_diagnose_command(app);
    pumeta::cli::add_compare_command(app);
    pumeta::cli::add_import_command(app);
    std::string command_line = "pumeta";
    for (int i = 1; i < argc; ++i) command_line += std::string(" ") + argv[i];
    pumeta::cli::add_eval_command(app, command_line);
    pumeta::cli::add_reproduce_command(app, command_line);
    pumeta::cli::add_report_command(app);

    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        // One line, like every other error (CLI11 would add a "Run with --help" line).
        std::fprintf(stderr, "pumeta: error: %s\n", e.what());
        return 2;
    } catch (const pumeta::InputError& e) {
        std::fprintf(stderr, "pumeta: error: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        // Only the first line: LibTorch errors append a C++ backtrace.
        std::string message = e.what();
        message = message.substr(0, message.find('\n'));
        std::fprintf(stderr, "pumeta: internal error: %s\n", message.c_str());
        return 1;
    }
    return pumeta::interrupt_requested() ? 130 : 0;
}
