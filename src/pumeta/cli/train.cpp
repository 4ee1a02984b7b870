// pumeta train --config CONFIG [--resume] [--max-minutes M] [--set key=value ...]
//              [--world-size W --rank R --master HOST:PORT]
#include "pumeta/cli/commands.h"
#include "pumeta/cli/config_file.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/train/trainer.h"

namespace pumeta::cli {

void add_train_command(CLI::App& app) {
    struct Args {
        std::string config;
        std::vector<std::string> overrides;
        bool resume = false;
        double max_minutes = 0;
        DistributedArgs distributed;
        std::vector<std::string> allow_changes;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand("train", "supervised pretraining of a backbone");
    command->add_option("--config", args->config, "training config JSON")->required();
    command->add_option("--set", args->overrides, "override a config field: key=value");
    command->add_flag("--resume", args->resume, "continue the run in run_dir from state.ckpt");
    command
        ->add_option("--max-minutes", args->max_minutes,
                     "checkpoint and stop after this many minutes (0 = no limit)")
        ->check(number_in(0, 1e7));
    command->add_option("--allow-change", args->allow_changes,
                        "with --resume: a config field (e.g. steps) allowed to differ from the "
                        "run's; repeatable");
    add_distributed_options(*command, args->distributed);
    command->callback([args] {
        nlohmann::json j = read_json_file(args->config);
        apply_overrides(j, args->overrides);
        apply_distributed_args(j, args->distributed);
        catch_interrupts();
        TrainResult result = train(TrainConfig::from_json(j), args->resume,
                                   args->max_minutes * 60.0, args->allow_changes);
        print_json({{"steps", result.steps},
                    {"best_val_cd", result.best_val_cd},
                    {"last_val_cd", result.last_val_cd}});
    });
}

}  // namespace pumeta::cli
