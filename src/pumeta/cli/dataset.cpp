// pumeta gen-shapes --count N --seed S -o DIR, and pumeta make-dataset --config C -o DIR.
#include "pumeta/data/dataset.h"

#include <spdlog/spdlog.h>

#include <filesystem>

#include "pumeta/cli/commands.h"
#include "pumeta/cli/config_file.h"
#include "pumeta/data/shapes.h"

namespace pumeta::cli {

void add_gen_shapes_command(CLI::App& app) {
    struct Args {
        int64_t count = 16;
        uint64_t seed = 0;
        std::string output;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand("gen-shapes", "write procedural CAD-like meshes");
    command->add_option("--count", args->count, "number of shapes")->check(integer_in(1, 1000000));
    command->add_option("--seed", args->seed, "seed of the first shape")->check(seed_value());
    command->add_option("-o,--output", args->output, "output directory (PLY meshes)")->required();
    command->callback([args] {
        std::filesystem::create_directories(args->output);
        for (int64_t i = 0; i < args->count; ++i) {
            uint64_t seed = args->seed + static_cast<uint64_t>(i);
            std::string file =
                (std::filesystem::path(args->output) / fmt::format("shape-{:06d}.ply", seed))
                    .string();
            write_mesh(file, generate_shape(seed));
        }
        spdlog::info("gen-shapes: wrote {} meshes to {}", args->count, args->output);
    });
}

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
