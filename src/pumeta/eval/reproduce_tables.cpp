#include "pumeta/eval/reproduce_tables.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>

#include "pumeta/core/error.h"
#include "pumeta/eval/benchmark_protocol.h"
#include "pumeta/inference/model_file.h"

namespace pumeta {

std::string TablePass::n_label() const { return "N = " + std::to_string(config.tta_steps); }

RunSpec TablePass::spec(const std::string& set, int64_t ratio, const std::string& method) const {
    RunSpec s;
    s.set = set;
    s.ratio = ratio;
    s.method = method;
    return s;
}

RunSpec TablePass::network_spec(const std::string& set, int64_t ratio, const std::string& model,
                                int64_t steps, std::optional<double> lr,
                                const std::string& noise) const {
    RunSpec s = spec(set, ratio, "network");
    s.model = model;
    s.tta_steps = steps;
    s.tta_lr = lr;
    s.noise = noise;
    return s;
}

const RunResult* TablePass::network(const std::string& set, int64_t ratio, const std::string& model,
                                    int64_t steps, std::optional<double> lr,
                                    const std::string& noise) {
    return &cells.get(network_spec(set, ratio, model, steps, lr, noise));
}

std::vector<const RunResult*> TablePass::per_set(
    const std::function<const RunResult*(const std::string&)>& run) const {
    return per_set(config.sets, run);
}

std::vector<const RunResult*> TablePass::per_set(
    const std::vector<std::string>& sets,
    const std::function<const RunResult*(const std::string&)>& run) const {
    std::vector<const RunResult*> runs;
    for (const std::string& set : sets) runs.push_back(run(set));
    return runs;
}

std::pair<std::optional<std::string>, std::optional<std::string>> TablePass::backbone_models(
    const std::string& backbone, int64_t ratio) {
    auto plain = models.find(backbone, ratio, false);
    auto meta = models.find(backbone, ratio, true);
    if (!plain)
        notes.push_back(fmt::format("{} at {}×: no model in {} (no rows)",
                                    config.label_of(backbone), ratio, config.models_dir));
    else if (!meta)
        notes.push_back(fmt::format("{} at {}×: no meta-trained model (no \"ours\" rows)",
                                    config.label_of(backbone), ratio));
    return std::make_pair(plain, meta);
}

namespace {

/// Data: the number of objects of each set (the cases of the "input" cells).
std::string counts_line(TablePass& pass, int64_t ratio) {
    std::string text;
    for (const std::string& set : pass.config.sets) {
        const RunResult& r = pass.cells.get(pass.spec(set, ratio, "input"));
        text += fmt::format("{}{} ({})", text.empty() ? "" : ", ", set,
                            r.ok ? std::to_string(r.cases.size()) + " objects" : "no cases");
    }
    return text;
}

/// Rows that need no backbone of pumeta's at ratio r on `sets`: the input itself, the sampling
/// floor (where the cases have a second GT sample), the midpoint baseline, the external
/// baselines whose program exists and the reference models whose file exists and serves r.
void reference_rows(TablePass& pass, const std::vector<std::string>& sets, int64_t r, bool floor,
                    std::vector<TableWriter::Row>& rows) {
    auto reference_row = [&](const std::string& label, const std::string& method) {
        rows.push_back({label,
                        pass.per_set(sets,
                                     [&](const std::string& set) {
                                         return &pass.cells.get(pass.spec(set, r, method));
                                     }),
                        {}});
    };
    reference_row("input, unchanged", "input");
    if (floor) reference_row("sampling floor (2nd GT sample)", "floor");
    reference_row("midpoint baseline", "midpoint");
    for (const ExternalBaseline& baseline : pass.config.external_baselines) {
        std::string command = with_bindir(baseline.command);
        std::string program = command.substr(0, command.find(' '));
        // A bare program name is left to the shell's PATH lookup.
        if (program.find('/') != std::string::npos && access(program.c_str(), X_OK) != 0) {
            pass.notes.push_back(fmt::format("{}: {} is not built or not executable (no row)",
                                             baseline.label, program));
            continue;
        }
        rows.push_back({baseline.label,
                        pass.per_set(sets,
                                     [&](const std::string& set) {
                                         RunSpec s = pass.spec(set, r, "external");
                                         s.label = baseline.label;
                                         // The template: a cell's identity does not depend on where
                                         // this binary was run from.
                                         s.command = baseline.command;
                                         return &pass.cells.get(s);
                                     }),
                        {}});
    }
    // A model file's row needs the file and a model that serves r; otherwise a note says why.
    auto usable = [&](const std::string& file, const std::string& absent,
                      const std::string& row_name) {
        std::error_code error;
        if (!std::filesystem::exists(file, error)) {
            pass.notes.push_back(absent);
            return false;
        }
        try {
            serve(file, r);
        } catch (const InputError& e) {
            pass.notes.push_back(fmt::format("{} at {}×: no row ({})", row_name, r, e.what()));
            return false;
        }
        return true;
    };
    auto model_row = [&](const std::string& label, const std::string& file, int64_t steps,
                         std::optional<double> lr, const std::vector<const RunResult*>& bases) {
        return TableWriter::Row{label,
                                pass.per_set(sets,
                                             [&](const std::string& set) {
                                                 return pass.network(set, r, file, steps, lr);
                                             }),
                                bases};
    };
    for (const ReferenceModel& reference : pass.config.reference_models) {
        if (!usable(reference.model,
                    fmt::format("{}: no file {} (no row; `pumeta import` makes it)",
                                reference.label, reference.model),
                    reference.label))
            continue;
        const TableWriter::Row plain =
            model_row(reference.label, reference.model, 0, std::nullopt, {});
        rows.push_back(plain);
        if (reference.tta_lr > 0)
            rows.push_back(model_row(fmt::format("{} + TTA w/o meta ({}, α = {:g})",
                                                 reference.label, pass.n_label(), reference.tta_lr),
                                     reference.model, pass.config.tta_steps, reference.tta_lr,
                                     plain.runs));
        if (!reference.meta_model.empty() &&
            usable(reference.meta_model,
                   fmt::format("{}: no meta-trained file {} (no \"ours\" row)", reference.label,
                               reference.meta_model),
                   reference.label + " + ours"))
            rows.push_back(model_row(fmt::format("{} + ours ({})", reference.label, pass.n_label()),
                                     reference.meta_model, pass.config.tta_steps, std::nullopt,
                                     plain.runs));
    }
}

/// " <what> only for <labels> (`<field>`: the others cost too much time here).": the note
/// of a table whose rows a config field limits to some backbones.
void rows_only_for(TablePass& pass, const std::vector<std::string>& only, const std::string& what,
                   const std::string& field) {
    pass.md() << " " << what << " only for";
    for (const std::string& b : only) pass.md() << " " << pass.config.label_of(b);
    pass.md() << " (`" << field << "`: the others cost too much time here).";
}

/// Each backbone's plain row at ratio r on `sets`, and its "+ ours" row paired with it.
void backbone_rows(TablePass& pass, const std::vector<std::string>& sets, int64_t r,
                   std::vector<TableWriter::Row>& rows) {
    const ReproduceConfig& config = pass.config;
    for (const std::string& backbone : config.backbones) {
        const auto found = pass.backbone_models(backbone, r);  // named: lambdas below use them
        const auto& plain = found.first;
        const auto& meta = found.second;
        if (!plain) continue;
        TableWriter::Row base{
            config.label_of(backbone),
            pass.per_set(sets,
                         [&](const std::string& set) { return pass.network(set, r, *plain, 0); }),
            {}};
        rows.push_back(base);
        if (!meta) continue;
        rows.push_back({config.label_of(backbone) + " + ours (" + pass.n_label() + ")",
                        pass.per_set(sets,
                                     [&](const std::string& set) {
                                         return pass.network(set, r, *meta, config.tta_steps);
                                     }),
                        base.runs});
    }
}

}  // namespace

void write_table1(TablePass& pass) {
    const ReproduceConfig& config = pass.config;
    const int64_t r = config.main_ratio;
    pass.md() << "## Table I: " << r << "× on every test set\n\n"
              << "Data: " << counts_line(pass, r) << ".\n\n";
    std::vector<TableWriter::Row> rows;
    reference_rows(pass, config.sets, r, /*floor=*/true, rows);
    backbone_rows(pass, config.sets, r, rows);
    nlohmann::json& t1 = pass.tables["table1"];
    pass.writer.table("Table I", config.sets, {kCd, kPsnr}, rows, t1);
    pass.md() << "Extended (Hausdorff and point-to-surface distances):\n\n";
    nlohmann::json& t1x = pass.tables["table1_extended"];
    pass.writer.table("Table I (extended)", config.sets, {kHd, kP2f}, rows, t1x);
}

void write_table2(TablePass& pass) {
    const ReproduceConfig& config = pass.config;
    const int64_t r = config.main_ratio;
    const std::string set = config.sets.front();
    std::vector<std::string> levels = {"clean"};
    for (const std::string& n : config.noise) levels.push_back(n);
    const std::vector<std::string>& only = config.noise_backbones;
    pass.md() << "## Table II: noise robustness, " << r << "× on " << set << "\n\n"
              << "Inputs with Gaussian noise of the relative protocol (`relX` = X % of the GT's "
                 "bounding-box diagonal, docs/data.md), scored against the clean GT.";
    const bool all_listed = std::all_of(
        config.backbones.begin(), config.backbones.end(),
        [&](const std::string& b) { return std::count(only.begin(), only.end(), b) > 0; });
    if (!only.empty() && !all_listed) rows_only_for(pass, only, "Rows", "noise_backbones");
    pass.md() << "\n\n";
    auto noise_of = [](const std::string& level) { return level == "clean" ? "" : level; };
    std::vector<TableWriter::Row> rows;
    {
        TableWriter::Row row{"midpoint baseline", {}, {}};
        for (const std::string& level : levels) {
            RunSpec s = pass.spec(set, r, "midpoint");
            s.noise = noise_of(level);
            row.runs.push_back(&pass.cells.get(s));
        }
        rows.push_back(row);
    }
    for (const std::string& backbone : config.backbones) {
        if (!only.empty() && !std::count(only.begin(), only.end(), backbone)) continue;
        const auto [plain, meta] = pass.backbone_models(backbone, r);
        if (!plain) continue;
        TableWriter::Row base{config.label_of(backbone), {}, {}};
        for (const std::string& level : levels)
            base.runs.push_back(pass.network(set, r, *plain, 0, std::nullopt, noise_of(level)));
        rows.push_back(base);
        if (!meta) continue;
        TableWriter::Row ours{config.label_of(backbone) + " + ours", {}, base.runs};
        for (const std::string& level : levels)
            ours.runs.push_back(
                pass.network(set, r, *meta, config.tta_steps, std::nullopt, noise_of(level)));
        rows.push_back(ours);
    }
    pass.writer.table("Table II", levels, {kCd}, rows, pass.tables["table2"]);
}

void write_table3(TablePass& pass) {
    const ReproduceConfig& config = pass.config;
    const int64_t r = config.main_ratio;
    const std::string set = config.sets.front();
    std::vector<std::string> groups;
    for (int64_t ratio : config.table3_ratios) groups.push_back(std::to_string(ratio) + "×");
    pass.md() << "## Table III: other ratios on " << set << "\n\n"
              << "A ratio without a native model uses a smaller-ratio model repeatedly (16× = 4× "
                 "twice; adaptation then runs in each pass), or, for a backbone whose weights "
                 "serve any ratio (a voxel model keeps the rN likeliest voxels), the "
              << r
              << "× model with "
                 "patches of (its patch size)·"
              << r << "/r input points.\n\n";
    std::vector<TableWriter::Row> rows;
    TableWriter::Row midpoint{"midpoint baseline", {}, {}};
    for (int64_t ratio : config.table3_ratios)
        midpoint.runs.push_back(&pass.cells.get(pass.spec(set, ratio, "midpoint")));
    rows.push_back(midpoint);
    for (const std::string& backbone : config.backbones) {
        TableWriter::Row base{config.label_of(backbone), {}, {}};
        TableWriter::Row ours{config.label_of(backbone) + " + ours", {}, {}};
        bool any_plain = false, any_meta = false;
        for (int64_t ratio : config.table3_ratios) {
            auto [plain, meta] = pass.backbone_models(backbone, ratio);
            base.runs.push_back(plain ? pass.network(set, ratio, *plain, 0) : nullptr);
            ours.runs.push_back(meta ? pass.network(set, ratio, *meta, config.tta_steps) : nullptr);
            any_plain |= bool(plain);
            any_meta |= bool(meta);
        }
        ours.bases = base.runs;
        if (any_plain) rows.push_back(base);
        if (any_meta) rows.push_back(ours);
    }
    pass.writer.table("Table III", groups, {kCd, kPsnr}, rows, pass.tables["table3"]);
}

void write_table4(TablePass& pass) {
    const ReproduceConfig& config = pass.config;
    const int64_t r = config.main_ratio;
    pass.md() << "## Table IV: ablation, " << r << "× (" << pass.n_label() << ")\n\n"
              << "\"ours, no adaptation\" is the meta-trained model used without adaptation: it "
                 "separates what meta-training changed in the weights from what adaptation "
                 "adds.\n\n";
    std::vector<TableWriter::Row> rows;
    for (const std::string& backbone : config.backbones) {
        const auto found = pass.backbone_models(backbone, r);  // named: lambdas below use them
        const auto& plain = found.first;
        const auto& meta = found.second;
        if (!plain) continue;
        const std::string label = config.label_of(backbone);
        TableWriter::Row base{
            label,
            pass.per_set([&](const std::string& set) { return pass.network(set, r, *plain, 0); }),
            {}};
        rows.push_back(base);
        std::optional<double> lr = config.tta_lr_for(backbone, r);
        TableWriter::Row tta{label + " + TTA w/o meta", pass.per_set([&](const std::string& set) {
                                 return pass.network(set, r, *plain, config.tta_steps, lr);
                             }),
                             base.runs};
        rows.push_back(tta);
        if (!meta) continue;
        std::vector<const RunResult*> ours = pass.per_set(
            [&](const std::string& set) { return pass.network(set, r, *meta, config.tta_steps); });
        rows.push_back({label + " + ours, no adaptation", pass.per_set([&](const std::string& set) {
                            return pass.network(set, r, *meta, 0);
                        }),
                        base.runs});
        rows.push_back({label + " + ours", ours, base.runs});
        rows.push_back({label + " + ours vs TTA w/o meta", ours, tta.runs});
    }
    pass.writer.table("Table IV", config.sets, {kCd, kPsnr}, rows, pass.tables["table4"]);
    pass.md() << "The last row of each backbone repeats \"ours\" with \"TTA w/o meta\" as its "
                 "base (equal N).\n\n";
}

void write_table5(TablePass& pass) {
    const ReproduceConfig& config = pass.config;
    const int64_t r = config.main_ratio;
    const std::string set = config.sets.front();
    pass.md() << "## Table V: number of adaptation steps, " << r << "× on " << set << "\n\n"
              << "Time is the wall time per object on this machine (mean), adaptation included; "
                 "the first row of each backbone is the plain backbone.\n\n";
    std::vector<TableWriter::Row> rows;
    for (const std::string& backbone : config.sweep_backbones) {
        const auto [plain, meta] = pass.backbone_models(backbone, r);
        if (!plain || !meta) continue;
        const std::string label = config.label_of(backbone);
        TableWriter::Row base{label + ", plain", {pass.network(set, r, *plain, 0)}, {}};
        rows.push_back(base);
        for (int64_t steps : config.steps_sweep)
            rows.push_back({label + " + ours, N = " + std::to_string(steps),
                            {pass.network(set, r, *meta, steps)},
                            base.runs});
    }
    pass.writer.table("Table V", {set}, {kCd, kPsnr, kSeconds}, rows, pass.tables["table5"]);
}

void write_table6(TablePass& pass) {
    const ReproduceConfig& config = pass.config;
    const ZeroShotBaseline& z = config.zero_shot;
    if (z.max_cases <= 0) return;
    const int64_t r = config.main_ratio;
    pass.md() << "## Table VI: internal learning vs external pretraining, " << r << "× (first "
              << z.max_cases << " objects of each set)\n\n"
              << "\"zero-shot\" trains the backbone from a fresh initialisation on each input's "
                 "own pairs (X↓, X) only, in the spirit of ZSPU: "
              << z.steps << " Adam steps of " << z.batch_patches << " patches, lr " << z.lr
              << ", random rotations; its time per object includes that training. Its base is "
                 "the pretrained backbone on the same objects, so the change shows what external "
                 "pretraining buys.";
    if (!z.backbones.empty())
        rows_only_for(pass, z.backbones, "Zero-shot rows", "zero_shot.backbones");
    pass.md() << "\n\n";
    auto first = [&](RunSpec s) {
        s.max_cases = z.max_cases;
        return &pass.cells.get(s);
    };
    std::vector<TableWriter::Row> rows;
    rows.push_back(
        {"midpoint baseline",
         pass.per_set([&](const std::string& set) { return first(pass.spec(set, r, "midpoint")); }),
         {}});
    for (const std::string& backbone : config.backbones) {
        const auto found = pass.backbone_models(backbone, r);  // named: lambdas below use them
        const auto& plain = found.first;
        const auto& meta = found.second;
        if (!plain) continue;
        const std::string label = config.label_of(backbone);
        TableWriter::Row base{label,
                              pass.per_set([&](const std::string& set) {
                                  return first(pass.network_spec(set, r, *plain, 0));
                              }),
                              {}};
        const std::vector<std::string>& only = z.backbones;
        if (only.empty() || std::count(only.begin(), only.end(), backbone))
            rows.push_back({label + " zero-shot (from scratch)",
                            pass.per_set([&](const std::string& set) {
                                RunSpec s = pass.spec(set, r, "zero-shot");
                                s.model = *plain;
                                s.zero_shot = z;
                                return first(s);
                            }),
                            base.runs});
        rows.push_back(base);
        if (!meta) continue;
        rows.push_back({label + " + ours (" + pass.n_label() + ")",
                        pass.per_set([&](const std::string& set) {
                            return first(pass.network_spec(set, r, *meta, config.tta_steps));
                        }),
                        base.runs});
    }
    pass.writer.table("Table VI", config.sets, {kCd, kPsnr, kSeconds}, rows, pass.tables["table6"]);
}

void write_table7(TablePass& pass) {
    const ReproduceConfig& config = pass.config;
    for (int64_t ratio : config.any_ratios) {
        pass.md() << "## Table VII, " << ratio << "×: a ratio only any-ratio models serve\n\n"
                  << "The plain models whose one file serves " << ratio
                  << "× (Meta-PU's scale-conditioned weights; PU-Dense keeps the rN likeliest "
                     "voxels); each is compared with the midpoint baseline on the same objects. "
                     "No adaptation here (Table III has \"ours\" at other ratios).\n\n";
        std::vector<TableWriter::Row> rows;
        TableWriter::Row midpoint{"midpoint baseline",
                                  pass.per_set([&](const std::string& set) {
                                      return &pass.cells.get(pass.spec(set, ratio, "midpoint"));
                                  }),
                                  {}};
        rows.push_back(midpoint);
        const std::vector<std::string>& backbones =
            config.any_ratio_backbones.empty() ? config.backbones : config.any_ratio_backbones;
        for (const std::string& backbone : backbones) {
            const std::optional<std::string> plain = pass.models.find(backbone, ratio, false);
            if (!plain) continue;
            rows.push_back({config.label_of(backbone), pass.per_set([&](const std::string& set) {
                                return pass.network(set, ratio, *plain, 0);
                            }),
                            midpoint.runs});
        }
        if (rows.size() == 1)
            pass.notes.push_back(
                fmt::format("Table VII, {}×: no model in {} serves it", ratio, config.models_dir));
        pass.writer.table(fmt::format("Table VII, {}×", ratio), config.sets, {kCd, kHd, kPsnr},
                          rows, pass.tables["table7"][fmt::format("x{}", ratio)]);
    }
}

void write_table8(TablePass& pass) {
    const ReproduceConfig& config = pass.config;
    if (config.scan_sets.empty()) return;
    for (int64_t r : config.scan_ratios) {
        pass.md() << "## Table VIII, " << r << "×: scans\n\n"
                  << "The scan sets (docs/data.md: ground truth = the whole sweep or strip, input "
                     "= a random 1/r of it) through the default pipeline, which treats scans and "
                     "measured returns as docs/design.md (\"Scans\") says; each \"ours\" row is "
                     "paired with its plain backbone.\n\n";
        std::vector<TableWriter::Row> rows;
        reference_rows(pass, config.scan_sets, r, /*floor=*/false, rows);
        backbone_rows(pass, config.scan_sets, r, rows);
        pass.writer.table(fmt::format("Table VIII, {}×", r), config.scan_sets, {kCd, kP2f}, rows,
                          pass.tables["table8"][fmt::format("x{}", r)]);
    }
}

void write_benchmark_tables(TablePass& pass) {
    for (const PublicBenchmark& benchmark : pass.config.benchmarks) {
        pass.md() << "## Table I on " << benchmark.label << "\n\n"
                  << "`" << benchmark.data_dir << "`, scored with the published protocol ("
                  << benchmark_protocol_description()
                  << "). Evaluation only: no model, step size or setting was chosen on it. HD is "
                     "the published tables' (hd_legacy); P2F the mean over objects of each "
                     "object's mean (the pooled mean when every object has rN points). Each "
                     "\"ours\" row is paired with its plain backbone.\n\n";
        for (int64_t r : benchmark.ratios) {
            const RunResult& input = pass.cells.get(pass.spec(benchmark.name, r, "input"));
            pass.md() << "### " << r << "× ("
                      << (input.ok ? std::to_string(input.cases.size()) + " objects"
                                   : "no objects: " + input.error)
                      << ")\n\n";
            if (!input.ok)
                pass.notes.push_back(fmt::format("{} at {}×: {}", benchmark.label, r, input.error));
            std::vector<TableWriter::Row> rows;
            reference_rows(pass, {benchmark.name}, r, /*floor=*/false, rows);
            backbone_rows(pass, {benchmark.name}, r, rows);
            pass.writer.table(fmt::format("Table I on {}, {}×", benchmark.name, r),
                              {benchmark.name},
                              {kBenchmarkCd, kBenchmarkHd, kBenchmarkP2f, kBenchmarkSeconds}, rows,
                              pass.tables["benchmarks"][benchmark.name][fmt::format("x{}", r)]);
        }
    }
}

}  // namespace pumeta
