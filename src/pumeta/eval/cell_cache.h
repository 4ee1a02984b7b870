// The cells of `pumeta reproduce`: one cell is one `evaluate_cases` run (a method on the cases
// of one set at one ratio; on a public benchmark's folder, one `evaluate_benchmark` run), kept in
// <out>/runs/<set>-x<r>[-<noise>]/<method>/ with the spec it was run with. A cell whose spec is
// unchanged is reused, an interrupted one resumes, and a lock file per cell lets several processes
// with the same output share the work.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "pumeta/eval/evaluate_benchmark.h"
#include "pumeta/eval/reproduce_config.h"

namespace pumeta {

/// One evaluation: a method on the cases of one set at one ratio.
struct RunSpec {
    std::string set;
    int64_t ratio = 0;
    std::string method = "network";  // network, midpoint, input, floor
    std::string model;               // network: checkpoint file
    int64_t tta_steps = 0;
    std::optional<double> tta_lr;  // empty: the model's own step sizes
    std::string noise;             // "" = clean input
    std::string label, command;    // external: the baseline's label and command ({bindir} kept)
    int64_t max_cases = -1;        // < 0: the config's max_cases
    ZeroShotBaseline zero_shot;    // method zero-shot (model: the architecture's checkpoint)

    /// The cell's directory under runs/: "<set>-x<r>[-<noise>]/<method and options>".
    std::string directory() const;
};

struct RunResult {
    std::string dir;  // relative to the output directory
    bool ok = false;
    std::string error;  // why there are no scores
    std::vector<std::string> cases;
    std::map<std::string, std::vector<double>> scores;  // column -> per case
    nlohmann::json summary;

    /// The mean of a column over the cases with a finite value; NaN without any.
    double mean(const std::string& column) const;
};

/// Every cell of one output directory, evaluated or reused once per process.
class CellCache {
  public:
    CellCache(const ReproduceConfig& config, std::filesystem::path out_dir,
              std::string command_line, bool evaluate);

    /// Cells that `--tables-only` left out because they were not evaluated yet.
    const std::set<std::string>& pending() const { return pending_; }

    /// The cell of `spec`, evaluated or reused; a placeholder without results while another
    /// process holds its lock (deferred()).
    const RunResult& get(const RunSpec& spec);

    /// Cells skipped in this pass because another process holds their lock; reset by
    /// start_pass().
    int64_t deferred() const { return deferred_; }
    void start_pass() { deferred_ = 0; }

  private:
    std::optional<RunResult> evaluate_or_reuse(const std::string& key, const RunSpec& spec);
    /// Runs evaluate_cases for a cell whose lock this process holds; false (with
    /// result.error) when it failed on its input.
    /// `benchmark`: the cell's public benchmark folder (evaluate_benchmark()), or null for
    /// a set of the dataset's cases (evaluate_cases()).
    bool evaluate(const std::string& key, const RunSpec& spec, const std::filesystem::path& dir,
                  const std::filesystem::path& cases, int64_t max_cases,
                  const nlohmann::json& identity, const BenchmarkLayout* benchmark,
                  RunResult& result);
    const nlohmann::json& identity_of(const std::string& key, const RunSpec& spec,
                                      const std::filesystem::path& cases, int64_t max_cases,
                                      const BenchmarkLayout* benchmark);

    const ReproduceConfig& config_;
    std::filesystem::path out_dir_;
    std::string command_line_;
    bool evaluate_ = true;
    std::set<std::string> pending_;
    std::map<std::string, RunResult> done_;
    std::map<std::string, nlohmann::json> identities_;  // by cell key
    // ok = false: a placeholder cell until a later pass.
    RunResult deferred_result_{"", false, "being evaluated by another process", {}, {}, {}};
    int64_t count_ = 0;
    int64_t deferred_ = 0;
};

}  // namespace pumeta
