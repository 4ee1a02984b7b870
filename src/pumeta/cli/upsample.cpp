// pumeta upsample IN -o OUT [--model M] [--ratio R] [--tta-steps N] ...; pumeta eval ...;
// pumeta meta-train --config C [--world-size W --rank R --master HOST:PORT].
#include <spdlog/spdlog.h>

#include <cmath>
#include <iostream>

#include "pumeta/cli/commands.h"
#include "pumeta/cli/config_file.h"
#include "pumeta/core/device.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/eval/evaluate_cases.h"
#include "pumeta/inference/model_file.h"
#include "pumeta/meta/meta_trainer.h"

namespace pumeta::cli {

namespace {

/// Options shared by upsample and eval.
struct ModelArgs {
    std::string model;
    int64_t ratio = 0;
    uint64_t seed = 0;
    int64_t tta_steps = -1;  // -1: the model's meta-trained N, or 0
    double tta_lr = -1;      // <0: the model's meta-trained alpha
    std::string tta_unit = "object";
    std::string tta_downsampler;  // the backbone's
    std::string tta_optimizer;    // the model's (sgd)
    int64_t batch_patches = 0;    // the backbone's
    std::string device = "cpu";
};

void add_model_options(CLI::App& command, ModelArgs& args) {
    command.add_option("--model", args.model,
                       "checkpoint (default: the shipped PU-GCN for --ratio, " +
                           default_model_path() + " when no ratio is given)");
    command.add_option("--ratio", args.ratio, "upsampling ratio (default: the model's)")
        ->check(integer_in(2, kMaxRatio));
    command.add_option("--seed", args.seed, "seed of the test-time downsampler")
        ->check(seed_value());
    command
        .add_option("--tta-steps", args.tta_steps,
                    "test-time adaptation steps N (default: a meta-trained model's N, else 0)")
        ->check(integer_in(0, 100000));
    command.add_option("--tta-lr", args.tta_lr, "inner step size (default: the model's)")
        ->check(number_above(0));
    command
        .add_option("--tta-unit", args.tta_unit,
                    "object: one adaptation on the input's patches, each downsampled; patch: "
                    "one per patch; cloud: one on patches of the downsampled whole input; "
                    "oracle (eval only): a diagnostic reference that adapts on the ground "
                    "truth")
        ->check(CLI::IsMember({"object", "patch", "cloud", "oracle"}));
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
                    "patches per forward pass (default: the backbone's fastest, 64 for PU-GCN "
                    "and Dis-PU, 2 for PU-Dense)")
        ->check(integer_in(1, 65536));
    command.add_option("--device", args.device, "cpu or cuda");
}

UpsampleOptions make_upsample_options(const ModelArgs& args, const InferenceModel& model) {
    UpsampleOptions o;
    o.ratio = args.ratio;
    o.seed = args.seed;
    o.batch_patches = args.batch_patches;
    o.tta_unit = args.tta_unit;
    o.tta_downsampler = args.tta_downsampler;
    set_adaptation(o, model, args.tta_lr);
    if (!args.tta_optimizer.empty()) o.meta.inner_optimizer = args.tta_optimizer;
    o.tta_steps =
        args.tta_steps >= 0 ? args.tta_steps : (model.meta_trained ? model.meta.inner_steps : 0);
    if (args.tta_lr < 0 && !model.meta_trained && o.tta_steps > 0) {
        spdlog::warn(
            "--tta-steps without --tta-lr on a model that is not meta-trained: using "
            "inner_lr {}",
            o.meta.inner_lr);
    }
    return o;
}

InferenceModel load_model(const ModelArgs& args) {
    std::string device = parse_device(args.device);
    InferenceModel model = load_inference_model(
        args.model.empty() ? default_model_for_ratio(args.ratio) : args.model, args.ratio);
    model.backbone->to(device);
    return model;
}

}  // namespace

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
                      "print n_in, n_out, seconds (and tta_* fields) as JSON");
    add_read_options(*command, args->read);
    add_model_options(*command, args->model);
    command->callback([args] {
        PointCloud cloud = read_point_cloud(args->input, args->read);
        if (args->method == "midpoint") {
            int64_t ratio = args->model.ratio > 0 ? args->model.ratio : 4;
            at::Tensor points = midpoint_upsample(cloud.points, ratio);
            write_point_cloud(args->output, {points});
            if (args->json) print_json({{"n_in", cloud.size()}, {"n_out", points.size(0)}});
            return;
        }
        InferenceModel model = load_model(args->model);
        UpsampleOptions options = make_upsample_options(args->model, model);
        options.show_progress = true;
        UpsampleResult result = upsample_cloud(*model.backbone, cloud.points, options);
        write_point_cloud(args->output, {result.points});
        nlohmann::json j = {
            {"n_in", result.n_in}, {"n_out", result.points.size(0)}, {"seconds", result.seconds}};
        if (options.tta_steps > 0) {
            j["tta_steps"] = options.tta_steps;
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
                options.tta_steps > 0
                    ? fmt::format(" (adaptation: {} steps, {:.2f} s, loss {:.3e} -> {:.3e})",
                                  options.tta_steps, result.tta_seconds, result.loss_before,
                                  result.loss_after)
                    : "");
    });
}

void add_eval_command(CLI::App& app, const std::string& command_line) {
    struct Args {
        std::string cases, output;
        EvalOptions eval;
        ModelArgs model;
    };
    auto args = std::make_shared<Args>();
    args->eval.command_line = command_line;
    CLI::App* command = app.add_subcommand("eval", "score a method on the test cases of a split");
    command->add_option("--cases", args->cases, "a cases/<set>/x<r> directory of make-dataset")
        ->required();
    command->add_option("-o,--output", args->output, "output directory (cases.csv, summary.json)")
        ->required();
    command
        ->add_option("--method", args->eval.method,
                     "network, midpoint, input, floor, external or zero-shot (a fresh model of "
                     "--model's architecture trained on each input alone)")
        ->check(CLI::IsMember({"network", "midpoint", "input", "floor", "external", "zero-shot"}));
    command
        ->add_option("--zero-shot-steps", args->eval.zero_shot.steps,
                     "method zero-shot: Adam steps per input")
        ->check(integer_in(1, 1000000));
    command
        ->add_option("--zero-shot-batch", args->eval.zero_shot.batch_patches,
                     "method zero-shot: patches per step")
        ->check(integer_in(1, 65536));
    command
        ->add_option("--zero-shot-lr", args->eval.zero_shot.lr,
                     "method zero-shot: Adam learning rate")
        ->check(number_above(0));
    command->add_option("--command", args->eval.external_command,
                        "method external: shell command with {input}, {output} (XYZ files) and "
                        "{ratio}, e.g. \"build/pumeta-ear {input} {output} --ratio {ratio}\"");
    command->add_option("--noise", args->eval.noise, "noisy input variant (rel1, abs0.01, ...)");
    command->add_option("--max-cases", args->eval.max_cases, "only the first N cases")
        ->check(integer_in(1, std::numeric_limits<int32_t>::max()));
    command->add_flag("--save-predictions", args->eval.save_predictions,
                      "write predictions to OUT/pred/");
    add_model_options(*command, args->model);
    command->callback([args] {
        InferenceModel model;
        if (args->eval.method == "network" || args->eval.method == "zero-shot") {
            model = load_model(args->model);
            args->eval.upsample = make_upsample_options(args->model, model);
        }
        nlohmann::json summary =
            evaluate_cases(args->cases, model.backbone.get(), args->eval, args->output);
        print_json(summary);
    });
}

void add_meta_train_command(CLI::App& app) {
    struct Args {
        RunArgs run;
        bool first_order = false;
        DistributedArgs distributed;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command =
        app.add_subcommand("meta-train", "meta-train a pretrained model (MAML, Algorithm 1)");
    add_run_options(*command, args->run, "meta-training");
    command->add_flag("--first-order", args->first_order, "first-order MAML (FOMAML)");
    add_distributed_options(*command, args->distributed);
    command->callback([args] {
        const RunArgs& run = args->run;
        nlohmann::json j = read_json_file(run.config);
        apply_overrides(j, run.overrides);
        if (args->first_order) j["meta"]["first_order"] = true;
        apply_distributed_args(j, args->distributed);
        catch_interrupts();
        MetaTrainResult r = meta_train(MetaTrainConfig::from_json(j), run.resume,
                                       run.max_minutes * 60.0, run.allow_changes);
        print_json({{"steps", r.steps},
                    {"val_cd_before", r.last.cd_before},
                    {"val_cd_after", r.last.cd_after},
                    {"val_inner_before", r.last.inner_loss_before},
                    {"val_inner_after", r.last.inner_loss_after},
                    {"val_alignment", r.last.alignment},
                    {"val_alignment_other", r.last.alignment_other},
                    {"best_val_cd_after", r.best_cd_after}});
    });
}

}  // namespace pumeta::cli
