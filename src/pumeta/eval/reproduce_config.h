// The config of `pumeta reproduce` (configs/reproduce.json): which backbones, baselines, sets,
// ratios and budgets the tables cover. Backbones are known here only by the names the config
// lists (model files <name>-x<r>[-meta].pt, their labels, step sizes).
#pragma once

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "pumeta/data/layout.h"

namespace pumeta {

/// A non-pumeta upsampler run through `pumeta eval --method external`.
struct ExternalBaseline {
    std::string label;
    /// Shell command with {input}, {output} (XYZ files), {ratio}, and {bindir} (the directory
    /// of the running program, where `pumeta-ear` is built).
    std::string command;

    static ExternalBaseline from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

/// A model file that is not one of pumeta's backbones' shipped files, e.g. released weights
/// imported with `pumeta import`: a plain reference row where the file exists and serves the
/// table's ratio.
struct ReferenceModel {
    std::string label;
    /// The model file (relative to the working directory).
    std::string model;
    /// > 0: a "+ TTA w/o meta" row, Algorithm 2 on `model` with this step size (chosen on
    /// validation data) and the config's tta_steps, paired with the plain row.
    double tta_lr = 0;
    /// Non-empty: a "+ ours" row, Algorithm 2 with this meta-trained file (e.g. meta-trained
    /// from the imported weights) and its learned step sizes, paired with the plain row; no
    /// row while the file does not exist.
    std::string meta_model;

    static ReferenceModel from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

/// A public benchmark's test folder (PU-GAN's or PU1K's published layout, read by
/// find_benchmark_layout()): the tables of "Table I on public benchmarks", scored with the
/// published protocol (eval/benchmark_protocol.h). Evaluation only: nothing is chosen on it.
struct PublicBenchmark {
    /// The name of its cells (runs/<name>-x<r>/...); must not be one of the test sets.
    std::string name;
    std::string label;
    /// The folder holding input_<N>/ and gt_<rN>/.
    std::string data_dir;
    /// input_<N> (0: the only one, or input_2048).
    int64_t input_points = 0;
    /// One table per ratio (each needs its gt_<rN>/ folder).
    std::vector<int64_t> ratios = {4, 16};

    static PublicBenchmark from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

/// `command` with every "{bindir}" replaced by the directory of this executable.
std::string with_bindir(std::string command);

/// The zero-shot internal-learning baseline (Table VI): a fresh backbone trained on each input
/// alone (eval method "zero-shot"). Costly, so it runs on the first `max_cases` objects only.
struct ZeroShotBaseline {
    int64_t steps = 300;
    int64_t batch_patches = 8;
    double lr = 1e-3;
    /// Objects per set (0 = none: no Table VI).
    int64_t max_cases = 5;
    /// Backbones with a zero-shot row (empty = all of ReproduceConfig::backbones).
    std::vector<std::string> backbones;

    static ZeroShotBaseline from_json(const nlohmann::json& j);
    nlohmann::json to_json() const;
};

struct ReproduceConfig {
    std::string dataset_dir = "data/dataset";
    std::string models_dir = "models";
    /// Backbones with rows, by registry name (the stem of their model files); a backbone
    /// without a shipped model for a ratio gets no row.
    std::vector<std::string> backbones;
    /// Row labels of backbones by name ("pugcn": "PU-GCN"); a backbone not listed is labelled
    /// by its name.
    std::map<std::string, std::string> backbone_labels;
    /// Classical baselines of Table I (rows only where the program exists).
    std::vector<ExternalBaseline> external_baselines;
    /// Reference rows of Tables I and VIII from other model files (imported released weights).
    std::vector<ReferenceModel> reference_models;
    /// Ratio of Tables I, II, IV and V (the paper's 8×).
    int64_t main_ratio = 8;
    /// Ratios of Table III (the paper's 4× and 16×).
    std::vector<int64_t> table3_ratios = {4, 16};
    /// Ratios of Table VII, served only by backbones whose one model takes any ratio
    /// (Meta-PU, PU-Dense's voxel ranking); empty = no Table VII.
    std::vector<int64_t> any_ratios = {3, 5, 6, 12};
    /// Backbones of Table VII (empty = all of `backbones`). May name backbones outside
    /// `backbones`: Table VII has no adaptation, so such a row costs plain evaluations only.
    std::vector<std::string> any_ratio_backbones;
    /// Sets of Table VIII (the scans table: every backbone, plain and "ours", against the
    /// input, the midpoint and the external baselines), e.g. the simulated sweeps and the
    /// aerial strips (docs/data.md); empty = no Table VIII.
    std::vector<std::string> scan_sets;
    /// Ratios of Table VIII.
    std::vector<int64_t> scan_ratios = {4, 8};
    /// Test sets (layout::kTestSets), the column groups of Tables I, IV and VI; the first is
    /// the set of Tables II, III and V.
    std::vector<std::string> sets{layout::kTestSets.begin(), layout::kTestSets.end()};
    /// Noisy input variants of Table II (keys of the cases' noisy inputs).
    std::vector<std::string> noise = {"rel0.5", "rel1", "rel2"};
    /// Backbones with Table II rows (empty = all of `backbones`).
    std::vector<std::string> noise_backbones;
    /// N of "ours" and of "TTA without meta".
    int64_t tta_steps = 5;
    std::string tta_unit = "object";
    /// N of Table V.
    std::vector<int64_t> steps_sweep = {1, 3, 5, 7, 9};
    /// Backbones of Table V (the paper uses Dis-PU; empty = no Table V rows).
    std::vector<std::string> sweep_backbones;
    /// Inner step size of "TTA without meta" per backbone ("pugcn") or per backbone and
    /// ratio ("pugcn-x8", which wins), chosen on validation data (models/README.md); a
    /// backbone not listed uses its model's inner_lr.
    std::map<std::string, double> tta_lr_without_meta;
    /// Seed of the test-time downsampler.
    uint64_t seed = 0;
    int64_t bootstrap_resamples = 2000;
    /// Only the first N cases of each set (0 = all).
    int64_t max_cases = 0;
    /// Predictions of the first N cases of every run are kept (runs/.../pred/) for the
    /// figures of `pumeta report`.
    int64_t figure_cases = 4;
    ZeroShotBaseline zero_shot;
    /// Tables I-VIII on dataset_dir (false: only the public benchmarks' tables).
    bool paper_tables = true;
    /// "Table I on public benchmarks": every backbone plain and + ours, the reference rows.
    std::vector<PublicBenchmark> benchmarks;
    std::string budget = "full";

    /// The benchmark whose cells carry the name `set`, or null (a test set of dataset_dir).
    const PublicBenchmark* benchmark(const std::string& set) const;

    /// tta_lr_without_meta for a backbone at a ratio, or none (the model's own).
    std::optional<double> tta_lr_for(const std::string& backbone, int64_t ratio) const;

    /// The label of a backbone's rows (backbone_labels, else its name).
    std::string label_of(const std::string& backbone) const;

    /// `budget` selects the object of j["budgets"] whose fields override the others.
    static ReproduceConfig from_json(nlohmann::json j, const std::string& budget);
    nlohmann::json to_json() const;
};

}  // namespace pumeta
