// pumeta sample MESH -n COUNT [--method poisson|uniform] [--seed S] -o OUT
#include "pumeta/cli/commands.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta::cli {

void add_sample_command(CLI::App& app) {
    struct Args {
        std::string input, output, method = "poisson";
        int64_t count = 0;
        uint64_t seed = 0;
        ReadOptions read;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand("sample", "sample points on a mesh surface");
    command->add_option("mesh", args->input, "input mesh")->required();
    command->add_option("-n,--count", args->count, "number of points")
        ->required()
        ->check(integer_in(1, int64_t{1} << 31));
    command->add_option("--method", args->method, "poisson (blue noise) or uniform (by area)")
        ->check(CLI::IsMember({"poisson", "uniform"}));
    command->add_option("--seed", args->seed, "random seed")->check(seed_value());
    command->add_option("-o,--output", args->output, "output cloud")->required();
    add_read_options(*command, args->read);
    command->callback([args] {
        TriangleMesh mesh = read_mesh(args->input, args->read);
        PointCloud cloud = args->method == "poisson"
                               ? sample_poisson_disk(mesh, args->count, args->seed)
                               : sample_uniform(mesh, args->count, args->seed);
        write_point_cloud(args->output, cloud);
    });
}

}  // namespace pumeta::cli
