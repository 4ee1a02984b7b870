// The tables of `pumeta reproduce` as markdown and JSON: one column per (group, metric), each
// cell a mean over objects with its paired change against the row's base.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "pumeta/eval/cell_cache.h"
#include "pumeta/eval/paired_stats.h"

namespace pumeta {

struct Metric {
    std::string column, label;
    double scale;  // printed value = mean / scale
    bool higher_is_better;
};

extern const Metric kCd;
extern const Metric kHd;
extern const Metric kP2f;
extern const Metric kPsnr;
extern const Metric kSeconds;
/// The columns of a public benchmark's cases.csv (evaluate_benchmark()), already × 10³.
extern const Metric kBenchmarkCd;
extern const Metric kBenchmarkHd;  ///< the published tables' (hd_legacy)
extern const Metric kBenchmarkP2f;
extern const Metric kBenchmarkSeconds;

/// A cell's number: 3 decimals (1 from 100 on), "—" when not finite.
std::string table_number(double v);

/// Writes tables one after the other into one markdown text (out()), and the paired
/// comparison behind every "(±x %)" as a line of details().
class TableWriter {
  public:
    /// bootstrap_resamples: of the 95 % interval of each paired comparison (seed 1).
    explicit TableWriter(int64_t bootstrap_resamples) : bootstrap_resamples_(bootstrap_resamples) {}

    struct Row {
        std::string label;
        std::vector<const RunResult*> runs;   // one per column group
        std::vector<const RunResult*> bases;  // paired comparison per group (or null)
    };

    /// A markdown table: one column per (group, metric). Appends its rows to json_table.
    void table(const std::string& table_id, const std::vector<std::string>& groups,
               const std::vector<Metric>& metrics, const std::vector<Row>& rows,
               nlohmann::json& json_table);

    std::ostringstream& out() { return out_; }
    std::vector<std::string>& details() { return details_; }

  private:
    /// A row's cells of one column group, written to out_ and json_row.
    void group_cells(const std::string& table_id, const std::string& group, const Row& row,
                     size_t g, const std::vector<Metric>& metrics, nlohmann::json& json_row);
    /// `run` against `base` on the cases they share (paired by case name).
    PairedComparison compare(const RunResult& base, const RunResult& run, const Metric& m) const;

    int64_t bootstrap_resamples_;
    std::ostringstream out_;
    std::vector<std::string> details_;
};

}  // namespace pumeta
