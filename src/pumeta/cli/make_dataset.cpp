// pumeta make-dataset [--config C] [--set key=value ...] -o DIR
#include "pumeta/cli/commands.h"
#include "pumeta/cli/config_file.h"
#include "pumeta/data/dataset.h"

namespace pumeta::cli {

void add_make_dataset_command(CLI::App& app) {
    struct Args {
        std::string config, output;
        std::vector<std::string> overrides;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand(
        "make-dataset", "build training patches and test cases from data/raw and the generator");
    command->add_option("--config", args->config, "dataset config JSON (default: built-in)");
    command->add_option("--set", args->overrides, "override a config field: key=value");
    command->add_option("-o,--output", args->output, "output directory")->required();
    command->callback([args] {
        nlohmann::json j =
            args->config.empty() ? nlohmann::json::object() : read_json_file(args->config);
        apply_overrides(j, args->overrides);
        nlohmann::json manifest = make_dataset(DatasetConfig::from_json(j), args->output);
        print_json(manifest["counts"]);
    });
}

}  // namespace pumeta::cli
