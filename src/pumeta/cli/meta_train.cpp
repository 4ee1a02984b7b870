// pumeta meta-train --config C [--resume] [--first-order] [--world-size W --rank R
//                   --master HOST:PORT]
#include "pumeta/cli/commands.h"
#include "pumeta/cli/config_file.h"
#include "pumeta/core/interrupt.h"
#include "pumeta/meta/meta_trainer.h"

namespace pumeta::cli {

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
                    {"best_val_cd_after", r.best_cd_after}});
    });
}

}  // namespace pumeta::cli
