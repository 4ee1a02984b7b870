// pumeta import --from FORMAT FILE -o OUT.pt: released weights of another implementation as a
// pumeta model file (models/import.h) that every command accepts.
#include "pumeta/models/import.h"

#include <spdlog/spdlog.h>

#include "pumeta/cli/commands.h"
#include "pumeta/core/error.h"
#include "pumeta/core/sha256.h"
#include "pumeta/models/checkpoint.h"

namespace pumeta::cli {

void add_import_command(CLI::App& app) {
    struct Args {
        std::string format, input, output;
        double step_size = 0;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand(
        "import", "convert released weights (a torch.save state dict) into a pumeta model");
    command->add_option("input", args->input, "the released file (.pth)")->required();
    command
        ->add_option("--from", args->format,
                     "whose weights: gradpu (Grad-PU) or pugaussian (PU-Gaussian)")
        ->required()
        ->check(CLI::IsMember(import_formats()));
    command->add_option("-o,--output", args->output, "pumeta model file to write (.pt)")
        ->required();
    command
        ->add_option("--step-size", args->step_size,
                     "gradpu: the refinement step of the original's test (default 50, as "
                     "for its PU-GAN weights; 500 for its PU1K weights)")
        ->check(number_above(0));
    command->callback([args] {
        nlohmann::json config = nlohmann::json::object();
        if (args->step_size > 0 && args->format != "gradpu")
            throw_input_error("--step-size", "applies to --from gradpu only");
        if (args->step_size > 0) config["step_size"] = args->step_size;
        std::unique_ptr<Backbone> model = import_weights(args->format, args->input, config);
        const nlohmann::json provenance = {
            {"format", args->format}, {"file", args->input}, {"sha256", sha256_file(args->input)}};
        save_checkpoint(args->output, *model, {{"imported_from", provenance}});
        spdlog::info("{}: {} parameters from {} ({}) -> {}", args->format,
                     count_parameters(model->parameters()), args->input,
                     provenance["sha256"].get<std::string>().substr(0, 12), args->output);
    });
}

}  // namespace pumeta::cli
