// pumeta eval --cases DIR -o OUT [--method M] [--model M] [--tta-steps N] ...
#include <limits>

#include "pumeta/cli/commands.h"
#include "pumeta/cli/model_args.h"
#include "pumeta/core/error.h"
#include "pumeta/data/layout.h"
#include "pumeta/eval/evaluate_cases.h"

namespace pumeta::cli {

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
                     "network, midpoint, input, floor, external, zero-shot (a fresh model of "
                     "--model's architecture trained on each input alone) or grid-floor (the "
                     "ground truth through --model's pipeline on its output grid)")
        ->check(CLI::IsMember(
            {"network", "midpoint", "input", "floor", "external", "zero-shot", "grid-floor"}));
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
    add_model_options(*command, args->model, /*oracle_unit=*/true);
    command->callback([args] {
        // The cases fix the ratio; --model (or the shipped model) must serve it.
        const int64_t ratio = layout::read_case_index(args->cases).at("ratio");
        if (args->model.ratio != 0 && args->model.ratio != ratio)
            throw_input_error(args->cases, "the cases are at ratio {}, not --ratio {}", ratio,
                              args->model.ratio);
        ServedModel served;
        if (args->eval.method == "network" || args->eval.method == "zero-shot" ||
            args->eval.method == "grid-floor") {
            served = load_model(args->model, ratio);
            args->eval.upsample = upsample_options(args->model, served);
            args->eval.oracle = args->model.tta_unit == "oracle";
        }
        nlohmann::json summary =
            evaluate_cases(args->cases, served.model.backbone.get(), args->eval, args->output);
        print_json(summary);
    });
}

}  // namespace pumeta::cli
