// pumeta diagnose --model M --data PATCHES [--patches V] [--seed S] [--sampler S]
#include "pumeta/eval/diagnose.h"

#include "pumeta/cli/commands.h"
#include "pumeta/core/error.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/inference/model_file.h"

namespace pumeta::cli {

void add_diagnose_command(CLI::App& app) {
    struct Args {
        std::string model, data;
        int64_t patches = 128;
        uint64_t seed = 1;
        std::string sampler;  // empty: the model's training sampler
    };
    auto args = std::make_shared<Args>();
    CLI::App* command =
        app.add_subcommand("diagnose",
                           "where a model's error on held-out patches comes from (its CD and the "
                           "decomposition its backbone reports)");
    command->add_option("--model", args->model, "checkpoint")->required();
    command->add_option("--data", args->data, "a patch set of make-dataset (val-x<r>.tensors)")
        ->required();
    command->add_option("--patches", args->patches, "validation patches (a seeded draw)")
        ->check(integer_in(1, 1000000));
    command->add_option("--seed", args->seed, "seed of the draw and of the inputs")
        ->check(seed_value());
    command
        ->add_option("--sampler", args->sampler,
                     "how inputs are drawn from the GT patches: fps, random or nonuniform "
                     "(default: the model's training sampler), so that models compare on "
                     "the same inputs")
        ->check(CLI::IsMember({"fps", "random", "nonuniform"}));
    command->callback([args] {
        InferenceModel model = load_inference_model(args->model);
        const std::string sampler = !args->sampler.empty()
                                        ? args->sampler
                                        : model.extra.value("sampler", std::string("fps"));
        PatchSet set = load_patch_set_for_ratio(args->data, model.backbone->ratio());
        ValidationSet val =
            make_validation_set(set, args->patches, parse_input_sampler(sampler), args->seed);
        print_json(diagnose_patches(*model.backbone, val));
    });
}

}  // namespace pumeta::cli
