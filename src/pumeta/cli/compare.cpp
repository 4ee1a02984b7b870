// pumeta compare BASE_DIR METHOD_DIR [--json]: paired intervals between two eval runs.
#include <iostream>
#include <nlohmann/json.hpp>

#include "pumeta/cli/commands.h"
#include "pumeta/eval/compare_runs.h"

namespace pumeta::cli {

void add_compare_command(CLI::App& app) {
    struct Args {
        std::string base, method;
        int64_t resamples = 2000;
        uint64_t seed = 1;
        bool json = false;
    };
    auto args = std::make_shared<Args>();
    CLI::App* command = app.add_subcommand(
        "compare",
        "paired comparison of two `pumeta eval` runs on the same cases: per metric, both means "
        "and a bootstrap 95 % interval of the per-case difference (method - base)");
    command->add_option("base", args->base, "output directory of the base run")->required();
    command->add_option("method", args->method, "output directory of the run compared with it")
        ->required();
    command->add_option("--resamples", args->resamples, "bootstrap resamples")
        ->check(integer_in(1, 1000000));
    command->add_option("--seed", args->seed, "bootstrap seed")->check(seed_value());
    command->add_flag("--json", args->json, "one JSON object on stdout");
    command->callback([args] {
        RunComparison c = compare_runs(args->base, args->method, args->resamples, args->seed);
        if (!args->json) {
            std::cout << format_run_comparison(c);
            return;
        }
        nlohmann::json j = {{"base", c.base_dir},
                            {"method", c.method_dir},
                            {"shared_cases", c.shared_cases},
                            {"only_in_base", c.only_in_base},
                            {"only_in_method", c.only_in_method},
                            {"metrics", nlohmann::json::object()}};
        for (const MetricComparison& m : c.metrics) {
            nlohmann::json metric = paired_json(m.paired);
            metric["mean_base"] = m.paired.mean_base;
            metric["mean_method"] = m.paired.mean_method;
            metric["higher_is_better"] = m.higher_is_better;
            j["metrics"][m.metric] = metric;
        }
        print_json(j);
    });
}

}  // namespace pumeta::cli
