#include "pumeta/eval/tables.h"

#include <fmt/format.h>

#include <cmath>
#include <map>

namespace pumeta {

const Metric kCd{"cd", "CD (×10⁻⁴)", 1e-4, false};
const Metric kHd{"hd", "HD (×10⁻²)", 1e-2, false};
const Metric kP2f{"p2f", "P2F (×10⁻³)", 1e-3, false};
const Metric kPsnr{"psnr", "PSNR (dB)", 1.0, true};
const Metric kSeconds{"seconds", "time (ms/object)", 1e-3, false};
const Metric kBenchmarkCd{"cd_1e3", "CD (×10⁻³)", 1.0, false};
const Metric kBenchmarkHd{"hd_legacy_1e3", "HD (×10⁻³)", 1.0, false};
const Metric kBenchmarkP2f{"p2f_1e3", "P2F (×10⁻³)", 1.0, false};
const Metric kBenchmarkSeconds{"seconds", "s/object", 1.0, false};

std::string table_number(double v) {
    if (!std::isfinite(v)) return "—";
    return fmt::format("{:.{}f}", v, std::abs(v) >= 100 ? 1 : 3);
}

void TableWriter::table(const std::string& table_id, const std::vector<std::string>& groups,
                        const std::vector<Metric>& metrics, const std::vector<Row>& rows,
                        nlohmann::json& json_table) {
    std::string header = "| method |", rule = "|---|";
    for (const std::string& group : groups)
        for (const Metric& m : metrics) {
            header += " " + (groups.size() > 1 ? group + " " : "") + m.label + " |";
            rule += "---|";
        }
    out_ << header << "\n" << rule << "\n";
    for (const Row& row : rows) {
        out_ << "| " << row.label << " |";
        nlohmann::json json_row = {{"label", row.label}, {"cells", nlohmann::json::array()}};
        for (size_t g = 0; g < groups.size(); ++g)
            group_cells(table_id, groups[g], row, g, metrics, json_row);
        out_ << "\n";
        json_table["rows"].push_back(json_row);
    }
    out_ << "\n";
}

void TableWriter::group_cells(const std::string& table_id, const std::string& group, const Row& row,
                              size_t g, const std::vector<Metric>& metrics,
                              nlohmann::json& json_row) {
    const RunResult* run = row.runs[g];
    const RunResult* base = g < row.bases.size() ? row.bases[g] : nullptr;
    for (const Metric& m : metrics) {
        double value = run ? run->mean(m.column) : std::nan("");
        std::string cell = table_number(value / m.scale);
        nlohmann::json json_cell = {
            {"group", group},
            {"metric", m.column},
            {"mean", std::isfinite(value) ? nlohmann::json(value) : nlohmann::json()}};
        if (run) json_cell["run"] = run->dir;
        if (run && !run->ok) json_cell["missing"] = run->error;
        if (run && run->ok) json_cell["count"] = run->cases.size();
        if (run && run->ok && base && base->ok && std::isfinite(value)) {
            PairedComparison c = compare(*base, *run, m);
            if (c.count > 0) {
                cell += fmt::format(" ({:+.1f} %{})", 100 * c.relative_change,
                                    c.excludes_zero() ? "†" : "");
                json_cell["vs_base"] = paired_json(c);
                details_.push_back(
                    fmt::format("- {}, {}, {}: {} vs its base: n = {}, mean difference {:.4g} "
                                "(95 % CI [{:.4g}, {:.4g}]), better on {:.0f} % of objects",
                                table_id, group, m.column, row.label, c.count, c.mean_difference,
                                c.ci_low, c.ci_high, 100 * c.fraction_improved));
            }
        }
        out_ << " " << cell << " |";
        json_row["cells"].push_back(json_cell);
    }
}

PairedComparison TableWriter::compare(const RunResult& base, const RunResult& run,
                                      const Metric& m) const {
    // Pair by case name.
    std::map<std::string, double> base_scores;
    for (size_t i = 0; i < base.cases.size(); ++i)
        base_scores[base.cases[i]] = base.scores.at(m.column)[i];
    std::vector<double> a, b;
    for (size_t i = 0; i < run.cases.size(); ++i) {
        auto it = base_scores.find(run.cases[i]);
        if (it == base_scores.end()) continue;
        a.push_back(it->second);
        b.push_back(run.scores.at(m.column)[i]);
    }
    return compare_paired(a, b, m.higher_is_better, bootstrap_resamples_, 1);
}

}  // namespace pumeta
