// pumeta upsample IN -o OUT [--model M] [--ratio R] [--tta-steps N] ...
#include <spdlog/spdlog.h>

#include "pumeta/cli/commands.h"
#include "pumeta/cli/model_args.h"

namespace pumeta::cli {

void add_upsample_command(CLI::App& app) {
    struct Args {
        std::string input, output, method = "network";
        bool json = false;
        ReadOptions read;
        ModelArgs model;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command =
        app.add_subcommand("upsample", "upsample a point cloud (with test-time adaptation)");
    command
        ->add_option("--method", args->method,
                     "network (the model) or midpoint (non-learned baseline)")
        ->check(CLI::IsMember({"network", "midpoint"}));
    command->add_option("input", args->input, "input cloud (any readable format)")->required();
    command->add_option("-o,--output", args->output, "output cloud")->required();
    command->add_flag("--json", args->json,
                      "print n_in, n_out, seconds, the model file (and tta_* fields) as JSON");
    add_read_options(*command, args->read);
    add_model_options(*command, args->model, /*oracle_unit=*/false);
    command->callback([args] {
        PointCloud cloud = read_point_cloud(args->input, args->read);
        if (args->method == "midpoint") {
            int64_t ratio = args->model.ratio > 0 ? args->model.ratio : kDefaultRatio;
            at::Tensor points = midpoint_upsample(cloud.points, ratio);
            write_point_cloud(args->output, {points});
            if (args->json) print_json({{"n_in", cloud.size()}, {"n_out", points.size(0)}});
            return;
        }
        ServedModel served = load_model(args->model, args->model.ratio);
        UpsampleOptions options = upsample_options(args->model, served);
        options.show_progress = true;
        UpsampleResult result = upsample_cloud(*served.model.backbone, cloud.points, options);
        write_point_cloud(args->output, {result.points});
        nlohmann::json j = {{"n_in", result.n_in},
                            {"n_out", result.points.size(0)},
                            {"seconds", result.seconds},
                            {"model", served.path}};
        if (options.adaptation.inner.steps > 0) {
            j["tta_steps"] = options.adaptation.inner.steps;
            j["tta_seconds"] = result.tta_seconds;
            j["loss_before"] = result.loss_before;
            j["loss_after"] = result.loss_after;
        }
        if (args->json)
            print_json(j);
        else
            spdlog::info(
                "upsample: {} -> {} points in {:.2f} s{}", result.n_in, result.points.size(0),
                result.seconds,
                options.adaptation.inner.steps > 0
                    ? fmt::format(" (adaptation: {} steps, {:.2f} s, loss {:.3e} -> {:.3e})",
                                  options.adaptation.inner.steps, result.tta_seconds,
                                  result.loss_before, result.loss_after)
                    : "");
    });
}

}  // namespace pumeta::cli
