// The tables of `pumeta reproduce`, one function per table: each asks the cell cache for its
// cells (evaluating or reusing them) and writes its section of tables.md and tables.json.
#pragma once

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pumeta/eval/cell_cache.h"
#include "pumeta/eval/reproduce_config.h"
#include "pumeta/eval/reproduce_models.h"
#include "pumeta/eval/tables.h"

namespace pumeta {

/// What the tables of one pass share: the cells, the writer of tables.md and tables.json, and
/// the notes of "Missing rows".
struct TablePass {
    TablePass(const ReproduceConfig& config, CellCache& cells, const ModelFiles& models)
        : config(config), cells(cells), models(models), writer(config.bootstrap_resamples) {}

    const ReproduceConfig& config;
    CellCache& cells;
    const ModelFiles& models;
    TableWriter writer;
    nlohmann::json tables;
    std::vector<std::string> notes;

    std::ostringstream& md() { return writer.out(); }
    /// "N = <tta_steps>", the N of the "ours" rows.
    std::string n_label() const;

    RunSpec spec(const std::string& set, int64_t ratio, const std::string& method) const;
    RunSpec network_spec(const std::string& set, int64_t ratio, const std::string& model,
                         int64_t steps, std::optional<double> lr = std::nullopt,
                         const std::string& noise = "") const;
    const RunResult* network(const std::string& set, int64_t ratio, const std::string& model,
                             int64_t steps, std::optional<double> lr = std::nullopt,
                             const std::string& noise = "");
    /// One run per set of config.sets (the column groups of Tables I and IV), or of `sets`.
    std::vector<const RunResult*> per_set(
        const std::function<const RunResult*(const std::string&)>& run) const;
    std::vector<const RunResult*> per_set(
        const std::vector<std::string>& sets,
        const std::function<const RunResult*(const std::string&)>& run) const;
    /// The plain and the meta-trained model of a backbone at a ratio; a missing one is noted.
    std::pair<std::optional<std::string>, std::optional<std::string>> backbone_models(
        const std::string& backbone, int64_t ratio);
};

/// Table I: the main ratio on every test set (with the extended metrics below it).
void write_table1(TablePass& pass);
/// Table II: noise robustness on the first set.
void write_table2(TablePass& pass);
/// Table III: the other ratios on the first set.
void write_table3(TablePass& pass);
/// Table IV: the ablation (TTA without meta, meta without adaptation).
void write_table4(TablePass& pass);
/// Table V: the number of adaptation steps.
void write_table5(TablePass& pass);
/// Table VI (beyond the paper): zero-shot internal learning vs external pretraining.
void write_table6(TablePass& pass);
/// Table VII (beyond the paper): ratios only any-ratio models serve, on every test set.
void write_table7(TablePass& pass);
/// Table VIII (beyond the paper): the scan sets (config.scan_sets) at each scan ratio.
void write_table8(TablePass& pass);
/// Table I on each public benchmark (config.benchmarks) at each of its ratios: the reference
/// rows and every backbone plain and + ours, scored with the published protocol.
void write_benchmark_tables(TablePass& pass);

}  // namespace pumeta
