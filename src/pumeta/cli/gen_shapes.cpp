// pumeta gen-shapes --count N --seed S -o DIR
#include <spdlog/spdlog.h>

#include <filesystem>

#include "pumeta/cli/commands.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/io.h"

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

}  // namespace pumeta::cli
