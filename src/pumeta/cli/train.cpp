// pumeta train --config CONFIG [--resume] [--max-minutes M] [--set key=value ...]
//              [--world-size W --rank R --master HOST:PORT]
#include "pumeta/cli/commands.h"
#include "pumeta/cli/config_file.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/train/trainer.h"

namespace pumeta::cli {

void add_train_command(CLI::App& app) {
    struct Args {
        RunArgs run;
        DistributedArgs distributed;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand("train", "supervised pretraining of a backbone");
    add_run_options(*command, args->run, "training");
    add_distributed_options(*command, args->distributed);
    command->callback([args] {
        const RunArgs& run = args->run;
        nlohmann::json j = read_json_file(run.config);
        apply_overrides(j, run.overrides);
        apply_distributed_args(j, args->distributed);
        catch_interrupts();
        TrainResult result =
            train(TrainConfig::from_json(j), run.resume, run.max_minutes * 60.0, run.allow_changes);
        print_json({{"steps", result.steps},
                    {"best_val_cd", result.best_val_cd},
                    {"last_val_cd", result.last_val_cd}});
    });
}

}  // namespace pumeta::cli
