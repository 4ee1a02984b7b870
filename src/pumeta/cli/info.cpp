// pumeta info FILE [--json]: what a cloud, mesh or model file holds.
#include <ATen/ATen.h>

#include <iostream>

#include "pumeta/cli/commands.h"
#include "pumeta/core/version.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/inference/model_file.h"
#include "pumeta/inference/upsample.h"

namespace pumeta::cli {

namespace {

struct InfoArgs {
    std::string path;
    bool json = false;
    ReadOptions read;
};

nlohmann::json geometry_info(const std::string& path, const ReadOptions& read) {
    Geometry geometry = read_geometry(path, read);
    const at::Tensor& points = geometry.cloud.points;
    nlohmann::json info;
    info["file"] = path;
    info["format"] = read.format.empty() ? format_from_path(path) : read.format;
    info["kind"] = geometry.is_mesh() ? "mesh" : "point_cloud";
    info["points"] = geometry.cloud.size();
    info["faces"] = geometry.is_mesh() ? geometry.faces.size(0) : 0;
    info["normals"] = geometry.cloud.has_normals();
    info["colors"] = geometry.cloud.has_colors();
    if (geometry.cloud.size() > 0) {
        at::Tensor lo = std::get<0>(points.min(0)).to(at::kDouble);
        at::Tensor hi = std::get<0>(points.max(0)).to(at::kDouble);
        std::vector<double> lo_v(lo.data_ptr<double>(), lo.data_ptr<double>() + 3);
        std::vector<double> hi_v(hi.data_ptr<double>(), hi.data_ptr<double>() + 3);
        info["bounds"] = {{"min", lo_v}, {"max", hi_v}};
    }
    if (!geometry.is_mesh() && geometry.cloud.size() >= 3) {
        // What `pumeta upsample` decides from: inputs whose nearest-neighbour spacing varies
        // this much are treated as scans (docs/design.md, "Scans").
        const double spread = spacing_spread(points);
        const SurfaceShape shape = surface_shape(points);
        info["spacing_spread"] = spread;
        info["surface_thickness"] = shape.thickness;
        info["surface_roughness"] = shape.roughness;
        info["input_kind"] = input_kind_name(classify_input(spread, shape));
    }
    return info;
}

bool is_model_file(const std::string& path) {
    auto dot = path.find_last_of('.');
    return dot != std::string::npos && (path.substr(dot) == ".pt" || path.substr(dot) == ".ckpt");
}

nlohmann::json model_info(const std::string& path) {
    InferenceModel model = load_inference_model(path);
    nlohmann::json info = {{"file", path},
                           {"kind", "model"},
                           {"backbone", model.backbone->name()},
                           {"ratio", model.backbone->ratio()},
                           // Whether --ratio may differ from "ratio" without repeating passes.
                           {"any_ratio", !model.backbone->config_for_ratio(2).is_null()},
                           {"parameters", count_parameters(model.backbone->parameters())},
                           {"config", model.backbone->config()},
                           {"meta_trained", model.meta_trained}};
    if (model.meta_trained) info["meta"] = MetaOptions::from_json(model.extra["meta"]).to_json();
    if (!model.adaptation.step_sizes.empty())
        info["step_sizes"] = step_sizes_to_json(model.adaptation.step_sizes);
    for (const char* key : {"step", "val_cd", "sampler", "imported_from"})
        if (model.extra.is_object() && model.extra.contains(key)) info[key] = model.extra[key];
    return info;
}

bool is_patch_set_file(const std::string& path) {
    auto dot = path.find_last_of('.');
    return dot != std::string::npos && path.substr(dot) == ".tensors";
}

nlohmann::json patch_set_info(const std::string& path) {
    PatchSet set = load_patch_set(path);
    int64_t generated = 0;
    for (const std::string& id : set.ids) generated += id.rfind("generator/", 0) == 0;
    return {{"file", path},
            {"kind", "patch set"},
            {"ratio", set.ratio},
            {"patch_points", set.patch_points},
            {"meshes", set.num_meshes()},
            {"generated_meshes", generated},
            {"patches", set.num_patches()},
            {"points", set.points.size(0)}};
}

void print_text(const nlohmann::json& info) {
    if (info["kind"] == "model" || info["kind"] == "patch set") {
        std::cout << info.dump(2) << "\n";
        return;
    }
    std::cout << info["file"].get<std::string>() << ": " << info["kind"].get<std::string>() << " ("
              << info["format"].get<std::string>() << ")\n";
    std::cout << "  points: " << info["points"] << "\n";
    if (info["faces"].get<int64_t>() > 0) std::cout << "  faces:  " << info["faces"] << "\n";
    std::cout << "  normals: " << (info["normals"].get<bool>() ? "yes" : "no")
              << ", colours: " << (info["colors"].get<bool>() ? "yes" : "no") << "\n";
    if (info.contains("bounds")) {
        const auto& lo = info["bounds"]["min"];
        const auto& hi = info["bounds"]["max"];
        std::cout << fmt::format("  bounds: [{:.6g}, {:.6g}, {:.6g}] .. [{:.6g}, {:.6g}, {:.6g}]\n",
                                 lo[0].get<double>(), lo[1].get<double>(), lo[2].get<double>(),
                                 hi[0].get<double>(), hi[1].get<double>(), hi[2].get<double>());
    }
    if (info.contains("input_kind")) {
        const std::string kind = info["input_kind"].get<std::string>();
        std::cout << fmt::format(
            "  spacing spread (q90/q10 of nearest-neighbour distance): {:.3g}\n"
            "  surface thickness (spread across the surface / spacing): {:.3g}\n"
            "  surface roughness (q10 of the distance off a local quadric / spacing): {:.3g}\n"
            "  taken for: {}{}\n",
            info["spacing_spread"].get<double>(), info["surface_thickness"].get<double>(),
            info["surface_roughness"].get<double>(), kind,
            kind == "scan"       ? " (upsample keeps the input points and follows scan lines)"
            : kind == "measured" ? " (upsample keeps the input points)"
                                 : " (an even sample of a surface)");
    }
}

}  // namespace

void add_info_command(CLI::App& app) {
    auto args = std::make_shared<InfoArgs>();
    CLI::App* command = app.add_subcommand("info", "counts, bounds and properties of a file");
    command
        ->add_option("file", args->path,
                     "point cloud, mesh, model (.pt) or patch set (.tensors) file")
        ->required();
    command->add_flag("--json", args->json, "one JSON object on stdout");
    add_read_options(*command, args->read);
    command->callback([args] {
        nlohmann::json info = is_model_file(args->path) ? model_info(args->path)
                              : is_patch_set_file(args->path)
                                  ? patch_set_info(args->path)
                                  : geometry_info(args->path, args->read);
        if (args->json) {
            // Which pumeta read the file: version, commit, LibTorch, BLAS.
            info["pumeta"] = build_info();
            print_json(info);
        } else
            print_text(info);
    });
}

}  // namespace pumeta::cli
