#include "pumeta/eval/reproduce.h"

#include <filesystem>

#include "pumeta/cli/commands.h"
#include "pumeta/cli/config_file.h"

namespace pumeta::cli {

void add_reproduce_command(CLI::App& app, const std::string& command_line) {
    struct Args {
        std::string config =
            (std::filesystem::path(PUMETA_SOURCE_DIR) / "configs" / "reproduce.json").string();
        std::string budget = "quick";
        std::string output;
        std::vector<std::string> overrides;
        bool tables_only = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand(
        "reproduce", "regenerate the paper's five tables on this repository's data");
    command->add_option("--config", args->config, "reproduction config JSON")
        ->capture_default_str();
    command->add_option("--budget", args->budget, "quick (a few cases, a smoke run) or full")
        ->check(CLI::IsMember({"quick", "full"}))
        ->capture_default_str();
    command->add_option("--set", args->overrides, "override a config field: key=value");
    command->add_option("-o,--output", args->output, "output directory (tables.md, runs/)")
        ->required();
    command->add_flag("--tables-only", args->tables_only,
                      "write the tables from the cells evaluated so far, evaluating none (the "
                      "others show as missing)");
    command->callback([args, command_line] {
        nlohmann::json j = read_json_file(args->config);
        apply_overrides(j, args->overrides);
        nlohmann::json tables = reproduce(ReproduceConfig::from_json(j, args->budget), args->output,
                                          command_line, !args->tables_only);
        std::fputs(tables.at("markdown").get<std::string>().c_str(), stdout);
    });
}

}  // namespace pumeta::cli
