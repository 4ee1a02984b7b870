#include <iostream>

#include "pumeta/cli/commands.h"

namespace pumeta::cli {

void add_read_options(CLI::App& command, ReadOptions& options) {
    command.add_option("--format", options.format,
                       "input format, overriding the extension (ply, xyz, off, obj, stl, pcd, "
                       "las)");
    command.add_flag("--drop-invalid", options.drop_invalid,
                     "drop points with NaN or infinite coordinates instead of failing");
}

void print_json(const nlohmann::json& value) { std::cout << value.dump() << std::endl; }

}  // namespace pumeta::cli
