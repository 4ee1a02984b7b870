// pumeta render CLOUD [MORE...] -o out.png: CPU point splatting with depth shading; several
// clouds make a grid with one shared frame (input / prediction / GT side by side), and
// --error-to GT colours each point by its distance to GT (render/render.h error_colors).
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
        std::vector<at::Tensor> colors(clouds.size());
        double scale = 0;
        if (reference.defined()) {
            std::vector<at::Tensor> distances;
            for (const at::Tensor& cloud : clouds)
                distances.push_back(knn(reference, cloud, 1).sq_distances.squeeze(1).sqrt());
            scale = error_scale(distances);
            colors = error_colors(distances, scale);
        }
        // Under an error picture, its scale: the colour bar in the files' own units.
        auto finish = [&](const Image& image) {
            if (scale <= 0) return image;
            const std::string gt = args->error_to.substr(args->error_to.find_last_of('/') + 1);
            return with_color_bar(image, 0, scale, "",
                                  "distance to " + gt + " in its units (yellow: top 5 %)");
        };
        for (size_t i = 0; i < clouds.size(); ++i) {
            images.push_back(render_image(clouds[i], options, colors[i]));
            std::string name = args->inputs[i];
            labels.push_back(name.substr(name.find_last_of('/') + 1));
        }
        if (images.size() == 1) {
            write_png(args->output, finish(images[0]));
            return;
        }
        int columns = args->columns > 0 ? args->columns : static_cast<int>(images.size());
        write_png(args->output, finish(render_grid(images, columns, labels)));
    });
}

}  // namespace pumeta::cli
