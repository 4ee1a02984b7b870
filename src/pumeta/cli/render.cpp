// pumeta render CLOUD [MORE...] -o out.png: CPU point splatting with depth shading; several
// clouds make a grid with one shared frame (input / prediction / GT side by side), and
// --error-to GT colours each point by its distance to GT.
#include "pumeta/render/render.h"

#include "pumeta/cli/commands.h"
#include "pumeta/geometry/knn.h"

namespace pumeta::cli {

void add_render_command(CLI::App& app) {
    struct Args {
        std::vector<std::string> inputs;
        std::string output, error_to;
        int size = 512;
        double elevation = 20, azimuth = 45, point_radius = 0;
        int columns = 0;
        ReadOptions read;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command =
        app.add_subcommand("render", "render clouds to a PNG (no GPU or display needed)");
    command->add_option("clouds", args->inputs, "one or more clouds (a grid when several)")
        ->required();
    command->add_option("-o,--output", args->output, "PNG file")->required();
    command->add_option("--size", args->size, "pixels per image side")->check(integer_in(16, 8192));
    command->add_option("--elevation", args->elevation, "view elevation in degrees")
        ->check(number_in(-90, 90));
    command->add_option("--azimuth", args->azimuth, "view azimuth in degrees")
        ->check(number_in(-360, 360));
    command->add_option("--point-radius", args->point_radius, "splat radius in pixels (0: auto)")
        ->check(number_in(0, 256));
    command->add_option("--columns", args->columns, "grid columns (0: all in one row)")
        ->check(integer_in(0, 1024));
    command->add_option("--error-to", args->error_to,
                        "colour points by distance to this reference cloud");
    add_read_options(*command, args->read);
    command->callback([args] {
        std::vector<at::Tensor> clouds;
        for (const std::string& path : args->inputs)
            clouds.push_back(read_point_cloud(path, args->read).points);
        RenderOptions options;
        options.width = options.height = args->size;
        options.elevation = args->elevation;
        options.azimuth = args->azimuth;
        options.point_radius = args->point_radius;
        options.frame = fit_frame(clouds.back());  // one frame for all: views line up
        at::Tensor reference;
        if (!args->error_to.empty())
            reference = read_point_cloud(args->error_to, args->read).points;
        std::vector<Image> images;
        std::vector<std::string> labels;
        for (size_t i = 0; i < clouds.size(); ++i) {
            at::Tensor colors;
            if (reference.defined()) {
                at::Tensor d = knn(reference, clouds[i], 1).sq_distances.squeeze(1).sqrt();
                colors = colormap(d, 0.0, 0.03 * options.frame.radius);
            }
            images.push_back(render_image(clouds[i], options, colors));
            std::string name = args->inputs[i];
            labels.push_back(name.substr(name.find_last_of('/') + 1));
        }
        if (images.size() == 1) {
            write_png(args->output, images[0]);
            return;
        }
        int columns = args->columns > 0 ? args->columns : static_cast<int>(images.size());
        write_png(args->output, render_grid(images, columns, labels));
    });
}

}  // namespace pumeta::cli

#include <filesystem>
#include <fstream>
#include <random>

#include "pumeta/data/layout.h"
#include "pumeta/data/patch_set.h"

namespace pumeta::cli {

namespace {

/// GT (grey) with the input on top (orange), as one coloured cloud.
Image render_pair(const at::Tensor& input, const at::Tensor& gt, const RenderOptions& base) {
    RenderOptions options = base;
    options.frame = fit_frame(gt);
    at::Tensor points = at::cat({gt, input});
    at::Tensor colors = at::cat({at::full({gt.size(0), 3}, 0.7f),
                                 at::tensor({0.95f, 0.45f, 0.1f}).expand({input.size(0), 3})});
    return render_image(points, options, colors);
}

}  // namespace

void add_contact_sheet_command(CLI::App& app) {
    struct Args {
        std::string dataset, output;
        int64_t ratio = 4;
        uint64_t seed = 0;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand(
        "contact-sheet", "pictures of a dataset: 16 training patches and 8 test cases");
    command->add_option("dataset", args->dataset, "a make-dataset directory")->required();
    command->add_option("-o,--output", args->output, "output directory for the PNGs")->required();
    command->add_option("--ratio", args->ratio, "which ratio's data to show")
        ->check(integer_in(2, kMaxRatio));
    command->add_option("--seed", args->seed, "which patches and cases are picked")
        ->check(seed_value());
    command->callback([args] {
        namespace fs = std::filesystem;
        fs::create_directories(args->output);
        RenderOptions options;
        options.width = options.height = 256;
        std::mt19937_64 rng(args->seed);

        PatchSet train =
            load_patch_set(layout::patch_set_path(args->dataset, "train", args->ratio).string());
        std::vector<Image> patches;
        std::vector<std::string> labels;
        for (int i = 0; i < 16; ++i) {
            int64_t s = std::uniform_int_distribution<int64_t>(0, train.num_patches() - 1)(rng);
            Batch pair = make_pair(train.gt_patch(s), train.patch_points, InputSampler::kFps, rng);
            patches.push_back(render_pair(pair.input, pair.gt, options));
            labels.push_back(train.ids[train.seeds[s][0].item<int64_t>()]);
        }
        write_png((fs::path(args->output) / "train-patches.png").string(),
                  render_grid(patches, 4, labels));

        std::vector<Image> cases;
        std::vector<std::string> case_labels;
        // Not kTestSets' order: the picks of the seeded generator follow this one.
        for (const char* set :
             {layout::kTestIndist, layout::kTestScans, layout::kTestHumans, layout::kTestAerial}) {
            fs::path dir = layout::cases_dir(args->dataset, set, args->ratio);
            if (!fs::exists(layout::case_index_path(dir))) continue;
            auto index = nlohmann::json::parse(std::ifstream(layout::case_index_path(dir)));
            auto list = index["cases"];
            for (int i = 0; i < 2 && !list.empty(); ++i) {
                auto pick = std::uniform_int_distribution<size_t>(0, list.size() - 1)(rng);
                fs::path c = dir / list[pick]["name"].get<std::string>();
                at::Tensor input = read_point_cloud((c / layout::kInputFile).string()).points;
                at::Tensor gt = read_point_cloud((c / layout::kGtFile).string()).points;
                RenderOptions o = options;
                o.frame = fit_frame(gt);
                cases.push_back(render_image(input, o));
                cases.push_back(render_image(gt, o));
                case_labels.push_back(std::string(set) + ": input");
                case_labels.push_back(list[pick]["id"].get<std::string>() + ": GT");
                list.erase(list.begin() + static_cast<std::ptrdiff_t>(pick));
            }
        }
        write_png((fs::path(args->output) / "test-cases.png").string(),
                  render_grid(cases, 4, case_labels));
    });
}

}  // namespace pumeta::cli
