#include "pumeta/eval/report.h"

#include <spdlog/spdlog.h>

#include "pumeta/cli/commands.h"

namespace pumeta::cli {

void add_report_command(CLI::App& app) {
    struct Args {
        std::string results, output;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand(
        "report", "write an HTML report with figures of a `pumeta reproduce` output directory");
    command->add_option("results", args->results, "output directory of pumeta reproduce")
        ->required();
    command->add_option("-o,--output", args->output, "report directory (index.html, figures/)")
        ->required();
    command->callback([args] {
        ReportSummary s = write_report(args->results, args->output);
        spdlog::info("report: {}/index.html with {} object figures and {} plots", args->output,
                     s.object_figures, s.plots);
    });
}

}  // namespace pumeta::cli
