// pumeta contact-sheet DATASET -o DIR [--ratio R] [--seed S]
#include "pumeta/render/contact_sheet.h"

#include <filesystem>

#include "pumeta/cli/commands.h"

namespace pumeta::cli {

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
        std::filesystem::path out(args->output);
        std::filesystem::create_directories(out);
        ContactSheet sheet = make_contact_sheet(args->dataset, args->ratio, args->seed);
        write_png((out / "train-patches.png").string(), sheet.train_patches);
        write_png((out / "test-cases.png").string(), sheet.test_cases);
    });
}

}  // namespace pumeta::cli
