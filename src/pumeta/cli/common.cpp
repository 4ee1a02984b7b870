#include <iostream>

#include "pumeta/cli/commands.h"
#include "pumeta/distributed/process_group.h"

namespace pumeta::cli {

void add_read_options(CLI::App& command, ReadOptions& options) {
    command.add_option("--format", options.format,
                       "input format, overriding the extension (ply, xyz, off, obj, stl, pcd, "
                       "las)");
    command.add_flag("--drop-invalid", options.drop_invalid,
                     "drop points with NaN or infinite coordinates instead of failing");
}

void add_distributed_options(CLI::App& command, DistributedArgs& args) {
    command
        .add_option("--world-size", args.world_size,
                    "processes of a distributed run (default: $WORLD_SIZE, else 1)")
        ->check(CLI::PositiveNumber);
    command.add_option("--rank", args.rank, "this process's rank (default: $RANK)")
        ->check(CLI::NonNegativeNumber);
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
