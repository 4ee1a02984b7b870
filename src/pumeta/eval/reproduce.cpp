#include "pumeta/eval/reproduce.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <thread>

#include "pumeta/eval/cell_cache.h"
#include "pumeta/eval/reproduce_models.h"
#include "pumeta/eval/reproduce_tables.h"
#include "pumeta/geometry/io/file.h"

namespace pumeta {

namespace fs = std::filesystem;

namespace {

/// The heading of tables.md: budget, command and the conventions of every table.
void write_preamble(const ReproduceConfig& config, const std::string& command_line,
                    std::ostringstream& md) {
    md << (config.paper_tables ? "# pumeta: the paper's tables on this repository's data\n\n"
                               : "# pumeta: Table I on public benchmarks\n\n")
       << "Budget `" << config.budget << "`"
       << (config.max_cases > 0 ? fmt::format(" (first {} cases of each set)", config.max_cases)
                                : std::string(" (all cases)"))
       << ". Command: `" << command_line << "`.\n\n";
    if (config.paper_tables)
        md << "Conventions (README, *Metrics*): every score of Tables I-VIII is computed in the "
              "GT frame of each case (the normalised mesh's unit sphere); CD = mean of both "
              "directions' mean squared nearest distances; HD = max of both directions' max "
              "distance; P2F = mean distance of predicted points to the mesh surface; PSNR = "
              "pc_error D1 with the GT's bounding-box diagonal as peak. ";
    md << "Each cell is a mean over objects. \"(±x %)\" is the change "
          "relative to the row's base (the plain backbone) on the same objects; † marks a "
          "paired difference whose 95 % bootstrap interval ("
       << config.bootstrap_resamples
       << " resamples of objects, seed 1) excludes 0. Test-time downsampler seed " << config.seed
       << "; adaptation unit `" << config.tta_unit << "`. \"TTA w/o meta\" = Algorithm 2 with "
       << "the merely pretrained model; \"ours\" = Algorithm 2 with the meta-trained model and its "
          "learned step sizes.\n\n";
}

/// "Missing rows" (the notes of every table and the cells `--tables-only` left out) and
/// "Paired comparisons" (the interval behind every "(±x %)").
void write_closing_sections(TablePass& pass) {
    std::vector<std::string>& notes = pass.notes;
    for (const std::string& cell : pass.cells.pending())
        notes.push_back("not evaluated yet (`--tables-only`): runs/" + cell);
    std::ostringstream& md = pass.md();
    if (!notes.empty()) {
        std::sort(notes.begin(), notes.end());
        notes.erase(std::unique(notes.begin(), notes.end()), notes.end());
        md << "## Missing rows\n\n";
        for (const std::string& note : notes) md << "- " << note << "\n";
        md << "\n";
        pass.tables["missing"] = notes;
    }
    md << "## Paired comparisons\n\n";
    for (const std::string& line : pass.writer.details()) md << line << "\n";
}

/// One pass over every table: evaluates (or reuses) each cell through `cells` and returns
/// tables.json with the markdown under "markdown".
nlohmann::json tables_pass(const ReproduceConfig& config, CellCache& cells,
                           const ModelFiles& models, const std::string& command_line) {
    TablePass pass(config, cells, models);
    pass.tables = {{"config", config.to_json()},
                   {"command", command_line},
                   {"dataset_path", fs::absolute(config.dataset_dir).string()}};
    write_preamble(config, command_line, pass.md());
    if (config.paper_tables) {
        write_table1(pass);
        write_table2(pass);
        write_table3(pass);
        write_table4(pass);
        write_table5(pass);
        write_table6(pass);
        write_table7(pass);
        write_table8(pass);
    }
    write_benchmark_tables(pass);
    write_closing_sections(pass);
    pass.tables["markdown"] = pass.md().str();
    return pass.tables;
}

}  // namespace

nlohmann::json reproduce(const ReproduceConfig& config, const std::string& out_dir,
                         const std::string& command_line, bool evaluate) {
    fs::create_directories(out_dir);
    CellCache cells(config, out_dir, command_line, evaluate);
    ModelFiles models(config.models_dir, config.main_ratio);
    for (;;) {
        cells.start_pass();
        nlohmann::json tables = tables_pass(config, cells, models, command_line);
        if (cells.deferred() == 0) {
            io::write_atomically((fs::path(out_dir) / "tables.md").string(),
                                 tables["markdown"].get<std::string>());
            io::write_atomically((fs::path(out_dir) / "tables.json").string(),
                                 tables.dump(2) + "\n");
            return tables;
        }
        // Another `pumeta reproduce` on the same output evaluates these cells.
        spdlog::info("reproduce: waiting for {} cells that another process is evaluating",
                     cells.deferred());
        std::this_thread::sleep_for(std::chrono::seconds(3));
    }
}

}  // namespace pumeta
