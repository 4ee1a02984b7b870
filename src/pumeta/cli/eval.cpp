// pumeta eval --cases DIR -o OUT [--method M] [--model M] [--tta-steps N] ...
// pumeta eval --benchmark pugan --data DIR -o OUT [--ratio R] [--input-points N] ...
#include <limits>

#include "pumeta/cli/commands.h"
#include "pumeta/cli/model_args.h"
#include "pumeta/core/error.h"
#include "pumeta/data/layout.h"
#include "pumeta/eval/evaluate_benchmark.h"
#include "pumeta/eval/evaluate_cases.h"

namespace pumeta::cli {

void add_eval_command(CLI::App& app, const std::string& command_line) {
    struct Args {
        std::string cases, benchmark, data, output;
        int64_t input_points = 0;
        EvalOptions eval;
        ModelArgs model;
    };
    auto args = std::make_shared<Args>();
    args->eval.command_line = command_line;
    CLI::App* command = app.add_subcommand(
        "eval", "score a method on the test cases of a split, or on a public benchmark");
    command->add_option("--cases", args->cases, "a cases/<set>/x<r> directory of make-dataset");
    command
        ->add_option("--benchmark", args->benchmark,
                     "score on a public benchmark's test folder (--data) with its published "
                     "protocol: pugan or pu1k (the same layout)")
        ->check(CLI::IsMember({"pugan", "pu1k"}));
    command->add_option("--data", args->data,
                        "--benchmark: the test folder (input_<N>/, gt_<rN>/, original_meshes/)");
    command
        ->add_option("--input-points", args->input_points,
                     "--benchmark: use input_<N>/ (default: the only one, else input_2048)")
        ->check(integer_in(1, std::numeric_limits<int32_t>::max()));
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
        if (args->cases.empty() == args->benchmark.empty())
            throw_input_error("eval", "give either --cases or --benchmark");
        if (!args->benchmark.empty()) {
            if (args->data.empty()) throw_input_error("eval", "--benchmark needs --data DIR");
            if (!args->eval.noise.empty())
                throw_input_error("eval", "--noise goes with --cases (a benchmark has one input)");
            // The folder fixes the ratio (--ratio chooses among its ground truths).
            BenchmarkLayout layout =
                find_benchmark_layout(args->data, args->input_points, args->model.ratio);
            layout.benchmark = args->benchmark;
            ServedModel served;
            if (args->eval.method == "network" || args->eval.method == "zero-shot" ||
                args->eval.method == "grid-floor") {
                served = load_model(args->model, layout.ratio);
                args->eval.upsample = upsample_options(args->model, served);
                args->eval.oracle = args->model.tta_unit == "oracle";
            }
            print_json(
                evaluate_benchmark(layout, served.model.backbone.get(), args->eval, args->output));
            return;
        }
        if (!args->data.empty() || args->input_points != 0)
            throw_input_error("eval", "--data and --input-points go with --benchmark");
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
