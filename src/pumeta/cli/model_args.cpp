#include "pumeta/cli/model_args.h"

#include "pumeta/cli/commands.h"
#include "pumeta/core/device.h"
#include "pumeta/data/patch_set.h"

namespace pumeta::cli {

void add_model_options(CLI::App& command, ModelArgs& args, bool oracle_unit) {
    command.add_option("--model", args.model,
                       "checkpoint (default: the shipped model for the ratio, named in " +
                           models_dir() + "/defaults.json)");
    command.add_option("--ratio", args.ratio, "upsampling ratio (default: the model's)")
        ->check(integer_in(2, kMaxRatio));
    command
        .add_option(
            "--seed", args.seed,
            "seed of the test-time downsampler and of the draws of a sampling model (PU-Gaussian)")
        ->check(seed_value());
    command
        .add_option("--tta-steps", args.tta_steps,
                    "test-time adaptation steps N (default: a meta-trained model's N, else 0)")
        ->check(integer_in(0, 100000));
    command.add_option("--tta-lr", args.tta_lr, "inner step size (default: the model's)")
        ->check(number_above(0));
    std::vector<std::string> units = {"object", "patch", "cloud"};
    std::string unit_help =
        "object (default): one adaptation on the input's patches, each downsampled; patch: "
        "one per patch; cloud: one on patches of the downsampled whole input";
    if (oracle_unit) {
        units.push_back("oracle");
        unit_help += "; oracle: a diagnostic reference that adapts on the ground truth";
    }
    command.add_option("--tta-unit", args.tta_unit, unit_help)->check(CLI::IsMember(units));
    command
        .add_option("--tta-downsampler", args.tta_downsampler,
                    "sampler of X↓ for adaptation: fps, random or nonuniform (default: the "
                    "backbone's training sampler)")
        ->check(CLI::IsMember({"fps", "random", "nonuniform"}));
    command
        .add_option("--tta-optimizer", args.tta_optimizer,
                    "inner steps: sgd (the paper's) or adam (learning rate --tta-lr); default "
                    "sgd")
        ->check(CLI::IsMember({"sgd", "adam"}));
    command
        .add_option("--batch-patches", args.batch_patches,
                    "patches per forward pass (default: the backbone's fastest)")
        ->check(integer_in(1, 65536));
    command
        .add_option("--spacing-bound", args.spacing_bound,
                    "keep each output point within this many times its nearest input point's "
                    "own spacing to its neighbour (0 = off)")
        ->check(CLI::Range(0.0, 1000.0));
    command
        .add_option("--whole-cloud", args.whole_cloud,
                    "run the network on the whole cloud (k-d tree parts of at most this many "
                    "points), scaled to the patches' point spacing; 0 = on patches (default: "
                    "the backbone's choice, whole clouds for PU-Dense)")
        ->check(integer_in(0, 100000000));
    command
        .add_option("--keep-input", args.keep_input,
                    "keep the input points among the outputs: on, off or auto (default: on for "
                    "inputs whose point spacing varies as a scan's)")
        ->check(CLI::IsMember({"auto", "on", "off"}));
    command
        .add_option("--line-projection", args.line_projection,
                    "move outputs onto the line of their nearest input point where its "
                    "neighbours are line-like (linearity above this, 0-1; 0 = off; default: "
                    "0.3 for scans, else off)")
        ->check(CLI::Range(0.0, 1.0));
    command
        .add_option("--select", args.select,
                    "how the final points are picked from the patches' outputs: fps (even), "
                    "ownership (follows the input's density) or auto (default: fps for irregularly "
                    "spaced inputs that are not scans and for inputs up to about 10,000 points, "
                    "else ownership)")
        ->check(CLI::IsMember({"auto", "fps", "ownership"}));
    command.add_option("--device", args.device, "cpu or cuda");
}

ServedModel load_model(const ModelArgs& args, int64_t ratio) {
    const std::string device = parse_device(args.device);
    ServedModel served = serve(args.model, ratio);
    served.model.backbone->to(device);
    return served;
}

UpsampleOptions upsample_options(const ModelArgs& args, const ServedModel& served) {
    AdaptationOverrides overrides;
    overrides.steps = args.tta_steps;
    overrides.step_size = args.tta_lr;
    if (!args.tta_unit.empty() && args.tta_unit != "oracle")
        overrides.unit = parse_adaptation_unit(args.tta_unit, "--tta-unit");
    if (!args.tta_downsampler.empty())
        overrides.downsampler = parse_input_sampler(args.tta_downsampler);
    if (!args.tta_optimizer.empty())
        overrides.optimizer = parse_inner_optimizer(args.tta_optimizer, "--tta-optimizer");
    UpsampleOptions options;
    options.ratio = served.ratio;
    options.seed = args.seed;
    options.batch_patches = args.batch_patches;
    if (args.spacing_bound) options.spacing_bound = *args.spacing_bound;
    if (args.whole_cloud) options.whole_cloud_points = *args.whole_cloud;
    if (args.line_projection) options.line_projection = *args.line_projection;
    if (args.select != "auto")
        options.selection = args.select == "fps" ? Selection::kFps : Selection::kOwnership;
    if (args.keep_input != "auto") options.keep_input = args.keep_input == "on";
    options.adaptation =
        adaptation_for(served.model.adaptation, served.model.meta_trained, overrides);
    return options;
}

}  // namespace pumeta::cli
