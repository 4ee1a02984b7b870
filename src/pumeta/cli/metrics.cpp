// pumeta metrics PRED GT [--mesh MESH] [--json]
#include "pumeta/metrics/metrics.h"

#include <iostream>

#include "pumeta/cli/commands.h"

namespace pumeta::cli {

void add_metrics_command(CLI::App& app) {
    struct Args {
        std::string pred, gt, mesh;
        bool json = false;
        ReadOptions read;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand(
        "metrics", "CD, HD, PSNR (pc_error D1) and P2F of a prediction, in the GT frame");
    command->add_option("pred", args->pred, "predicted cloud")->required();
    command->add_option("gt", args->gt, "ground-truth cloud")->required();
    command->add_option("--mesh", args->mesh, "ground-truth mesh for P2F (GT coordinates)");
    command->add_flag("--json", args->json, "one JSON object on stdout");
    add_read_options(*command, args->read);
    command->callback([args] {
        PointCloud pred = read_point_cloud(args->pred, args->read);
        PointCloud gt = read_point_cloud(args->gt, args->read);
        TriangleMesh mesh;
        if (!args->mesh.empty()) mesh = read_mesh(args->mesh, args->read);
        MetricReport r = evaluate(pred.points, gt.points, args->mesh.empty() ? nullptr : &mesh);
        if (args->json) {
            nlohmann::json j = {{"cd", r.cd},     {"hd", r.hd},     {"hd_legacy", r.hd_legacy},
                                {"psnr", r.psnr}, {"p2f", nullptr}, {"n_pred", r.n_pred},
                                {"n_gt", r.n_gt}};
            if (r.p2f) j["p2f"] = *r.p2f;
            print_json(j);
            return;
        }
        std::cout << fmt::format(
            "CD        {:.6e}\nHD        {:.6e}\nHD legacy {:.6e}\n"
            "PSNR      {:.4f} dB\n",
            r.cd, r.hd, r.hd_legacy, r.psnr);
        if (r.p2f) std::cout << fmt::format("P2F       {:.6e}\n", *r.p2f);
        std::cout << fmt::format("points    {} predicted, {} ground truth\n", r.n_pred, r.n_gt);
    });
}

}  // namespace pumeta::cli
