// `pumeta reproduce` end to end on a miniature dataset with tiny untrained models: every
// table is written, cells equal the per-run eval summaries, comparisons are paired, missing
// models and cases are reported, and a second run reuses every evaluation whose inputs did
// not change.
#include "pumeta/eval/reproduce.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/inference/upsample.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

class ReproduceTest : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        dir_ = new test::TempDir();
        config_ = new nlohmann::json(test::make_tiny_reproduction(dir_->path()));
        // Row labels come from the config, as in configs/reproduce.json.
        (*config_)["backbone_labels"] = {{"pugcn", "PU-GCN"}, {"dispu", "Dis-PU"}};
    }
    static void TearDownTestSuite() {
        delete config_;
        delete dir_;
    }

    static ReproduceConfig config() { return ReproduceConfig::from_json(*config_, "quick"); }

    /// The quick config with a models folder `name` holding PU-GCN's 4x model and a small
    /// Meta-PU file (every ratio 2..16), and no noise, sweep or zero-shot tables.
    static nlohmann::json any_ratio_config(const std::string& name) {
        fs::path models = dir_->path() / name;
        fs::create_directories(models);
        fs::copy_file(dir_->path() / "models" / "pugcn-x4.pt", models / "pugcn-x4.pt",
                      fs::copy_options::overwrite_existing);
        save_checkpoint((models / "metapu.pt").string(),
                        *make_backbone(small_backbone_config("metapu")));
        nlohmann::json j = *config_;
        j["models_dir"] = models.string();
        j["backbone_labels"]["metapu"] = "Meta-PU";
        j["noise"] = nlohmann::json::array();
        j["sweep_backbones"] = nlohmann::json::array();
        j["zero_shot"]["max_cases"] = 0;
        return j;
    }

    static test::TempDir* dir_;
    static nlohmann::json* config_;
};
test::TempDir* ReproduceTest::dir_ = nullptr;
nlohmann::json* ReproduceTest::config_ = nullptr;

nlohmann::json read_json(const fs::path& file) {
    return nlohmann::json::parse(std::ifstream(file));
}

const nlohmann::json& row(const nlohmann::json& table, const std::string& label) {
    for (const nlohmann::json& r : table.at("rows"))
        if (r.at("label") == label) return r;
    throw std::runtime_error("no row " + label);
}

TEST_F(ReproduceTest, WritesEveryTableWithCellsEqualToTheEvalSummaries) {
    fs::path out = dir_->path() / "results";
    nlohmann::json tables = reproduce(config(), out.string(), "test");
    std::string md = test::read_file((out / "tables.md").string());
    for (const char* title : {"## Table I:", "## Table II:", "## Table III:", "## Table IV:",
                              "## Table V:", "## Table VI:", "## Paired comparisons"})
        EXPECT_NE(md.find(title), std::string::npos) << title;

    // Table I, PU-GCN on test-indist: the mean CD of its eval run.
    nlohmann::json summary = read_json(out / "runs/test-indist-x4/pugcn-x4/summary.json");
    const nlohmann::json& plain = row(tables.at("table1"), "PU-GCN");
    EXPECT_EQ(plain["cells"][0]["metric"], "cd");
    // (The tables read the per-case CSV, written with 9 significant digits.)
    const double cd = summary["cd"]["mean"].get<double>();
    EXPECT_NEAR(plain["cells"][0]["mean"].get<double>(), cd, 1e-8 * cd);
    const int64_t count = summary["count"];
    EXPECT_GE(count, 1);
    EXPECT_LE(count, 2);  // max_cases

    // "ours" is compared with the plain backbone on the same objects.
    const nlohmann::json& ours = row(tables.at("table1"), "PU-GCN + ours (N = 2)");
    ASSERT_TRUE(ours["cells"][0].contains("vs_base"));
    EXPECT_EQ(ours["cells"][0]["vs_base"]["count"], count);
    nlohmann::json ours_summary =
        read_json(out / "runs/test-indist-x4/pugcn-x4-meta.tta2/summary.json");
    EXPECT_NEAR(ours["cells"][0]["vs_base"]["mean_difference"].get<double>(),
                ours_summary["cd"]["mean"].get<double>() - cd, 1e-8 * cd);
    EXPECT_EQ(ours_summary["tta"]["steps"], 2);

    // TTA without meta uses the configured step size; Table V's time column is present.
    EXPECT_TRUE(fs::exists(out / "runs/test-indist-x4/pugcn-x4.tta2.lr0.02/cases.csv"));
    EXPECT_EQ(row(tables.at("table5"), "PU-GCN, plain")["cells"][2]["metric"], "seconds");

    // The external baseline "copy" returns the input (through XYZ files): the input's scores.
    const double input_cd = row(tables.at("table1"), "input, unchanged")["cells"][0]["mean"];
    EXPECT_NEAR(row(tables.at("table1"), "copy")["cells"][0]["mean"].get<double>(), input_cd,
                1e-5 * input_cd);

    // 16× has no cases in this dataset; Dis-PU has no model: both reported, not invented.
    const nlohmann::json& t3 = row(tables.at("table3"), "PU-GCN");
    EXPECT_TRUE(t3["cells"][2]["mean"].is_null());
    EXPECT_NE(t3["cells"][2]["missing"].get<std::string>().find("no test cases"),
              std::string::npos);
    bool dispu_missing = false;
    for (const auto& note : tables.at("missing"))
        dispu_missing |=
            note.get<std::string>().find("Dis-PU at 4×: no model") != std::string::npos;
    EXPECT_TRUE(dispu_missing);
    bool absent_missing = false;
    for (const auto& note : tables.at("missing"))
        absent_missing |= note.get<std::string>().find(
                              "absent: /nonexistent/upsampler is not built") != std::string::npos;
    EXPECT_TRUE(absent_missing);

    // Table VII: no model of this config serves 3×, so only the midpoint baseline, and a note.
    const nlohmann::json& t7 = tables.at("table7").at("x3");
    ASSERT_EQ(t7.at("rows").size(), 1u);
    EXPECT_GE(row(t7, "midpoint baseline")["cells"][0]["count"].get<int64_t>(), 1);
    bool unserved = false;
    for (const auto& note : tables.at("missing"))
        unserved |= note.get<std::string>().find("Table VII, 3×: no model") != std::string::npos;
    EXPECT_TRUE(unserved);

    // Table VI: the zero-shot baseline on the first object of each set, paired with the
    // pretrained backbone on that same object; its run records the training budget.
    const nlohmann::json& zero_shot = row(tables.at("table6"), "PU-GCN zero-shot (from scratch)");
    EXPECT_EQ(zero_shot["cells"][0]["count"], 1);
    EXPECT_EQ(zero_shot["cells"][0]["vs_base"]["count"], 1);
    EXPECT_EQ(row(tables.at("table6"), "PU-GCN")["cells"][0]["count"], 1);
    nlohmann::json zs_summary =
        read_json(out / "runs/test-indist-x4/zero-shot-pugcn-x4.s3.first1/summary.json");
    EXPECT_EQ(zs_summary["method"], "zero-shot");
    EXPECT_EQ(zs_summary["zero_shot"]["steps"], 3);
    EXPECT_GT(zs_summary["zero_shot"]["training_seconds"]["mean"].get<double>(), 0);
}

TEST_F(ReproduceTest, TableSevenHasTheModelsThatServeItsRatioPairedWithTheMidpoint) {
    // One Meta-PU file serves 3× (scale-conditioned weights); PU-GCN's 4× model does not.
    nlohmann::json j = any_ratio_config("models-any-ratio");
    j["backbones"] = {"pugcn", "metapu"};
    fs::path out = dir_->path() / "any-ratio";
    nlohmann::json tables = reproduce(ReproduceConfig::from_json(j, "quick"), out.string(), "test");

    const nlohmann::json& t7 = tables.at("table7").at("x3");
    EXPECT_EQ(t7.at("rows").size(), 2u);  // the midpoint and Meta-PU
    const nlohmann::json& metapu = row(t7, "Meta-PU");
    nlohmann::json summary = read_json(out / "runs/test-indist-x3/metapu/summary.json");
    EXPECT_EQ(summary["ratio"], 3);
    const double cd = summary["cd"]["mean"].get<double>();
    EXPECT_NEAR(metapu["cells"][0]["mean"].get<double>(), cd, 1e-8 * cd);
    // Paired with the midpoint baseline on the same objects.
    nlohmann::json midpoint = read_json(out / "runs/test-indist-x3/midpoint/summary.json");
    ASSERT_TRUE(metapu["cells"][0].contains("vs_base"));
    EXPECT_EQ(metapu["cells"][0]["vs_base"]["count"], summary["count"]);
    EXPECT_NEAR(metapu["cells"][0]["vs_base"]["mean_difference"].get<double>(),
                cd - midpoint["cd"]["mean"].get<double>(), 1e-6 * cd);
    EXPECT_NE(test::read_file((out / "tables.md").string()).find("## Table VII, 3×"),
              std::string::npos);
}

TEST_F(ReproduceTest, TableEightHasTheScanSetsWithEveryBackboneAndItsPairedOurs) {
    // The mesh sets stand in for scan sets here: the table only needs cases.
    nlohmann::json j = *config_;
    j["scan_sets"] = {"test-scans", "test-indist"};
    j["scan_ratios"] = {4};
    j["noise"] = nlohmann::json::array();
    j["sweep_backbones"] = nlohmann::json::array();
    j["zero_shot"]["max_cases"] = 0;
    fs::path out = dir_->path() / "scans-table";
    nlohmann::json tables = reproduce(ReproduceConfig::from_json(j, "quick"), out.string(), "test");

    const nlohmann::json& t8 = tables.at("table8").at("x4");
    std::vector<std::string> labels;
    for (const nlohmann::json& r : t8.at("rows")) labels.push_back(r.at("label"));
    // No sampling floor (scans have no second GT); Dis-PU has no model here.
    EXPECT_EQ(labels, (std::vector<std::string>{"input, unchanged", "midpoint baseline", "copy",
                                                "PU-GCN", "PU-GCN + ours (N = 2)"}));
    const nlohmann::json& ours = row(t8, "PU-GCN + ours (N = 2)");
    ASSERT_EQ(ours.at("cells").size(), 4u);  // CD and P2F of the two sets
    nlohmann::json summary = read_json(out / "runs/test-indist-x4/pugcn-x4-meta.tta2/summary.json");
    const double cd = summary["cd"]["mean"].get<double>();
    EXPECT_NEAR(ours["cells"][2]["mean"].get<double>(), cd, 1e-8 * cd);
    nlohmann::json plain = read_json(out / "runs/test-indist-x4/pugcn-x4/summary.json");
    ASSERT_TRUE(ours["cells"][2].contains("vs_base"));
    EXPECT_NEAR(ours["cells"][2]["vs_base"]["mean_difference"].get<double>(),
                cd - plain["cd"]["mean"].get<double>(), 1e-6 * cd);
    EXPECT_NE(test::read_file((out / "tables.md").string()).find("## Table VIII, 4×: scans"),
              std::string::npos);
    // Without scan sets there is no Table VIII.
    EXPECT_FALSE(reproduce(config(), (dir_->path() / "no-scans").string(), "test",
                           /*evaluate=*/false)
                     .contains("table8"));
}

// Reference models (e.g. imported released weights) get a plain row where their file exists;
// a missing file is a note, not a failure.
TEST_F(ReproduceTest, ReferenceModelsGetAPlainRowWhereTheirFileExists) {
    nlohmann::json j = *config_;
    j["scan_sets"] = {"test-indist"};
    j["scan_ratios"] = {4};
    j["noise"] = nlohmann::json::array();
    j["sweep_backbones"] = nlohmann::json::array();
    j["zero_shot"]["max_cases"] = 0;
    const fs::path imported = dir_->path() / "imported-pugaussian.pt";
    save_checkpoint(imported.string(), *make_backbone(small_backbone_config("pugaussian")));
    const fs::path meta = dir_->path() / "models" / "pugcn-x4-meta.pt";
    j["reference_models"] = {{{"label", "PU-Gaussian (imported)"},
                              {"model", imported.string()},
                              {"tta_lr", 0.001},
                              {"meta_model", meta.string()}},
                             {{"label", "Absent"}, {"model", (dir_->path() / "no.pt").string()}},
                             {{"label", "Unmeta"},
                              {"model", imported.string()},
                              {"meta_model", (dir_->path() / "no-meta.pt").string()}}};
    fs::path out = dir_->path() / "reference-models";
    nlohmann::json tables = reproduce(ReproduceConfig::from_json(j, "quick"), out.string(), "test");

    const nlohmann::json& reference = row(tables.at("table8").at("x4"), "PU-Gaussian (imported)");
    nlohmann::json summary =
        read_json(out / "runs/test-indist-x4" / imported.stem() / "summary.json");
    const double cd = summary["cd"]["mean"].get<double>();
    EXPECT_NEAR(reference["cells"][0]["mean"].get<double>(), cd, 1e-8 * cd);
    const std::string missing = tables.at("missing").dump();
    EXPECT_NE(missing.find("Absent: no file"), std::string::npos) << missing;
    EXPECT_EQ(missing.find("PU-Gaussian (imported)"), std::string::npos) << missing;
    EXPECT_NE(missing.find("Unmeta: no meta-trained file"), std::string::npos) << missing;

    // Its "+ TTA w/o meta" and "+ ours" rows, each paired with the plain row.
    const nlohmann::json& tta = row(tables.at("table8").at("x4"),
                                    "PU-Gaussian (imported) + TTA w/o meta (N = 2, α = 0.001)");
    ASSERT_TRUE(tta["cells"][0].contains("vs_base"));
    nlohmann::json tta_summary =
        read_json(out / "runs/test-indist-x4" / (imported.stem().string() + ".tta2.lr0.001") /
                  "summary.json");
    EXPECT_EQ(tta_summary["tta"]["steps"], 2);
    EXPECT_NEAR(tta["cells"][0]["vs_base"]["mean_difference"].get<double>(),
                tta_summary["cd"]["mean"].get<double>() - cd, 1e-8 * cd);
    const nlohmann::json& ours =
        row(tables.at("table8").at("x4"), "PU-Gaussian (imported) + ours (N = 2)");
    ASSERT_TRUE(ours["cells"][0].contains("vs_base"));
    EXPECT_TRUE(fs::exists(out / "runs/test-indist-x4/pugcn-x4-meta.tta2/summary.json"));
    EXPECT_THROW(
        ReproduceConfig::from_json(
            {{"reference_models", {{{"label", "x"}, {"model", "m.pt"}, {"tta_lr", -1}}}}}, "full"),
        InputError);
}

/// A public benchmark folder in the published layout: two generated meshes, 256-point inputs,
/// ground truths at 4x and 16x.
fs::path make_benchmark_folder(const fs::path& root) {
    for (const char* folder : {"input_256", "gt_1024", "gt_4096", "original_meshes"})
        fs::create_directories(root / folder);
    for (uint64_t seed : {21, 22}) {
        const TriangleMesh mesh = generate_shape(seed);
        const std::string name = fmt::format("shape{}", seed);
        write_mesh((root / "original_meshes" / (name + ".off")).string(), mesh);
        write_point_cloud((root / "input_256" / (name + ".xyz")).string(),
                          {sample_uniform(mesh, 256, seed).points, {}, {}});
        for (int64_t n : {1024, 4096})
            write_point_cloud((root / fmt::format("gt_{}", n) / (name + ".xyz")).string(),
                              {sample_uniform(mesh, n, seed + 100).points, {}, {}});
    }
    return root;
}

TEST_F(ReproduceTest, PublicBenchmarkTablesHaveEveryRowScoredAsEvalBenchmark) {
    nlohmann::json j = *config_;
    j["paper_tables"] = false;
    const fs::path data = make_benchmark_folder(dir_->path() / "minibench");
    j["benchmarks"] = {{{"name", "minibench"},
                        {"label", "two generated shapes"},
                        {"data_dir", data.string()},
                        {"ratios", {4, 16}}},
                       {{"name", "nogt"}, {"data_dir", data.string()}, {"ratios", {8}}}};
    fs::path out = dir_->path() / "benchmark-tables";
    nlohmann::json tables = reproduce(ReproduceConfig::from_json(j, "full"), out.string(), "test");

    // Only the benchmark tables: no cell of the dataset's test sets was evaluated.
    EXPECT_FALSE(tables.contains("table1"));
    EXPECT_FALSE(fs::exists(out / "runs/test-indist-x4"));
    const std::string md = test::read_file((out / "tables.md").string());
    const size_t heading = md.find("## Table I on two generated shapes\n");
    ASSERT_NE(heading, std::string::npos) << md;
    EXPECT_LT(heading, md.find("### 4× (2 objects)"));
    EXPECT_LT(md.find("### 4× (2 objects)"), md.find("### 16× (2 objects)"));

    for (int64_t r : {4, 16}) {
        const nlohmann::json& table =
            tables.at("benchmarks").at("minibench").at(fmt::format("x{}", r));
        // Every cell is the mean over objects of its evaluate_benchmark run's summary.
        for (const auto& [label, cell] :
             std::vector<std::pair<std::string, std::string>>{{"input, unchanged", "input"},
                                                              {"midpoint baseline", "midpoint"},
                                                              {"PU-GCN", "pugcn-x4"}}) {
            const nlohmann::json summary =
                read_json(out / fmt::format("runs/minibench-x{}", r) / cell / "summary.json");
            EXPECT_EQ(summary.at("objects"), 2);
            EXPECT_EQ(summary.at("ratio"), r);
            const nlohmann::json& first = row(table, label).at("cells").at(0);
            EXPECT_EQ(first.at("metric"), "cd_1e3");
            const double cd = summary.at("cd_1e3").get<double>();
            EXPECT_NEAR(first.at("mean").get<double>(), cd, 1e-7 * cd) << label << " " << r;
        }
        // "+ ours" is paired with the plain backbone on both objects.
        const nlohmann::json& ours = row(table, "PU-GCN + ours (N = 2)").at("cells").at(0);
        ASSERT_TRUE(ours.contains("vs_base"));
        EXPECT_EQ(ours.at("vs_base").at("count"), 2);
        const nlohmann::json tta =
            read_json(out / fmt::format("runs/minibench-x{}/pugcn-x4-meta.tta2/summary.json", r));
        EXPECT_EQ(tta.at("tta").at("steps"), 2);
    }
    // The upsampled clouds are scored: the input scores worse than the midpoint at 4x.
    const nlohmann::json& x4 = tables.at("benchmarks").at("minibench").at("x4");
    EXPECT_GT(row(x4, "input, unchanged")["cells"][0]["mean"].get<double>(),
              row(x4, "midpoint baseline")["cells"][0]["mean"].get<double>());
    // A ratio without ground truths leaves its rows missing with the folder's reason.
    EXPECT_NE(md.find("no gt_2048 folder for ratio 8"), std::string::npos) << md;

    // A second run reuses every cell; a changed folder (a third object) makes new ones.
    nlohmann::json again = reproduce(ReproduceConfig::from_json(j, "full"), out.string(), "test");
    EXPECT_EQ(again.at("benchmarks"), tables.at("benchmarks"));
    const std::string shape = "shape21";
    for (const char* folder : {"input_256", "gt_1024", "gt_4096"})
        fs::copy_file(data / folder / (shape + ".xyz"), data / folder / "shape23.xyz");
    fs::copy_file(data / "original_meshes" / (shape + ".off"),
                  data / "original_meshes" / "shape23.off");
    nlohmann::json grown = reproduce(ReproduceConfig::from_json(j, "full"), out.string(), "test");
    EXPECT_EQ(read_json(out / "runs/minibench-x4/midpoint/summary.json").at("objects"), 3);
    EXPECT_EQ(row(grown.at("benchmarks").at("minibench").at("x4"), "PU-GCN")
                  .at("cells")
                  .at(0)
                  .at("count"),
              3);

    // A benchmark may not take the name of a test set.
    j["benchmarks"][0]["name"] = "test-indist";
    EXPECT_THROW(ReproduceConfig::from_json(j, "full"), InputError);
}

TEST_F(ReproduceTest, TableSevenTakesItsOwnBackbonesWithoutTheirOtherTables) {
    // any_ratio_backbones names Meta-PU for Table VII only: the other tables keep `backbones`.
    nlohmann::json j = any_ratio_config("models-any-ratio-only");
    j["backbones"] = {"pugcn"};
    j["any_ratio_backbones"] = {"metapu"};
    fs::path out = dir_->path() / "any-ratio-only";
    nlohmann::json tables = reproduce(ReproduceConfig::from_json(j, "quick"), out.string(), "test");

    const nlohmann::json& t7 = tables.at("table7").at("x3");
    EXPECT_EQ(t7.at("rows").size(), 2u);  // the midpoint and Meta-PU
    EXPECT_NO_THROW(row(t7, "Meta-PU"));
    EXPECT_TRUE(fs::exists(out / "runs/test-indist-x3/metapu/summary.json"));
    for (const nlohmann::json& r : tables.at("table1").at("rows"))
        EXPECT_EQ(r.at("label").get<std::string>().find("Meta-PU"), std::string::npos);
    EXPECT_FALSE(fs::exists(out / "runs/test-indist-x4/metapu"));
    EXPECT_EQ(tables.at("config").at("any_ratio_backbones"), nlohmann::json({"metapu"}));
}

TEST_F(ReproduceTest, ASecondRunReusesUnchangedEvaluationsAndRedoesChangedModels) {
    fs::path out = dir_->path() / "resume";
    nlohmann::json first = reproduce(config(), out.string(), "test");
    fs::path plain_csv = out / "runs/test-indist-x4/pugcn-x4/cases.csv";
    fs::path meta_csv = out / "runs/test-indist-x4/pugcn-x4-meta.tta2/cases.csv";
    auto plain_time = fs::last_write_time(plain_csv);
    auto meta_time = fs::last_write_time(meta_csv);

    nlohmann::json again = reproduce(config(), out.string(), "test");
    EXPECT_EQ(fs::last_write_time(plain_csv), plain_time);
    EXPECT_EQ(again.at("table1"), first.at("table1"));

    // A different meta-trained model (new weights, new hash) is evaluated again.
    fs::path models = dir_->path() / "models";
    fs::path saved = dir_->path() / "meta-backup.pt";
    fs::copy_file(models / "pugcn-x4-meta.pt", saved, fs::copy_options::overwrite_existing);
    test::save_tiny_meta_model((models / "pugcn-x4-meta.pt").string(), 3);
    reproduce(config(), out.string(), "test");
    fs::copy_file(saved, models / "pugcn-x4-meta.pt", fs::copy_options::overwrite_existing);
    EXPECT_EQ(fs::last_write_time(plain_csv), plain_time);
    EXPECT_NE(fs::last_write_time(meta_csv), meta_time);

    // New weights for the plain model: its cells run again, but the zero-shot baseline, which
    // only takes the architecture from it and trains from scratch, is reused.
    fs::path zero_shot_csv;
    for (const auto& entry : fs::directory_iterator(out / "runs/test-indist-x4"))
        if (entry.path().filename().string().rfind("zero-shot-", 0) == 0)
            zero_shot_csv = entry.path() / "cases.csv";
    ASSERT_TRUE(fs::exists(zero_shot_csv));
    auto zero_shot_time = fs::last_write_time(zero_shot_csv);
    fs::copy_file(models / "pugcn-x4.pt", saved, fs::copy_options::overwrite_existing);
    test::save_tiny_model((models / "pugcn-x4.pt").string(), 5);
    reproduce(config(), out.string(), "test");
    fs::copy_file(saved, models / "pugcn-x4.pt", fs::copy_options::overwrite_existing);
    EXPECT_NE(fs::last_write_time(plain_csv), plain_time);
    EXPECT_EQ(fs::last_write_time(zero_shot_csv), zero_shot_time);
}

TEST_F(ReproduceTest, AnInterruptedCellResumesAfterItsLastFinishedCase) {
    fs::path out = dir_->path() / "interrupted";
    reproduce(config(), out.string(), "test");
    fs::path cell = out / "runs/test-indist-x4/pugcn-x4";
    // cases.csv, its rows without the timing (field 7), which differs from run to run.
    auto cases_csv = [&] {
        std::vector<std::string> lines;
        std::ifstream in(cell / "cases.csv");
        for (std::string line; std::getline(in, line);) {
            if (lines.empty()) {
                lines.push_back(line);
                continue;
            }
            size_t at = 0;
            for (int comma = 0; comma < 7; ++comma) at = line.find(',', at) + 1;
            lines.push_back(line.erase(at, line.find(',', at) - at));
        }
        return lines;
    };
    const std::vector<std::string> lines = cases_csv();
    ASSERT_EQ(lines.size(), 2u);  // header + the set's one case
    // The case's row marked by a CD no evaluation gives (and with its timing column blank).
    std::string marked = lines[1];
    size_t cd_at = 0;
    for (int comma = 0; comma < 3; ++comma) cd_at = marked.find(',', cd_at) + 1;
    marked.replace(cd_at, marked.find(',', cd_at) - cd_at, "0.5");
    // Interrupted with `tail` after the header; spec.partial.json = the cell's identity.
    auto interrupt = [&](const std::string& tail, const nlohmann::json& identity) {
        std::ofstream(cell / "cases.csv.tmp") << lines[0] << "\n" << tail;
        fs::remove(cell / "cases.csv");
        fs::remove(cell / "summary.json");
        fs::remove(cell / "spec.json");
        std::ofstream(cell / "spec.partial.json") << identity.dump();
    };
    const nlohmann::json identity = read_json(cell / "spec.json");
    // A network cell is tied to the weights and to the pipeline that produced its points.
    EXPECT_TRUE(identity.contains("model_sha256"));
    EXPECT_EQ(identity.value("pipeline", int64_t(0)), kPipelineVersion);

    // The finished row is kept, not evaluated again.
    interrupt(marked + "\n", identity);
    reproduce(config(), out.string(), "test");
    EXPECT_EQ(cases_csv(), (std::vector<std::string>{lines[0], marked}));
    EXPECT_NEAR(read_json(cell / "summary.json").at("cd").at("mean").get<double>(), 0.5, 1e-12);
    EXPECT_FALSE(fs::exists(cell / "spec.partial.json"));
    EXPECT_EQ(read_json(cell / "spec.json"), identity);

    // A row cut short by the interruption (no newline) is evaluated again.
    interrupt(marked.substr(0, marked.size() - 1), identity);
    reproduce(config(), out.string(), "test");
    EXPECT_EQ(cases_csv(), lines);

    // So is a row that does not parse (here a CD with a stray letter).
    std::string garbled = marked;
    garbled.replace(cd_at, 3, "0.5x");
    interrupt(garbled + "\n", identity);
    reproduce(config(), out.string(), "test");
    EXPECT_EQ(cases_csv(), lines);

    // A partial cell of other settings (here another seed) starts afresh.
    nlohmann::json other = identity;
    other["seed"] = 12345;
    interrupt(marked + "\n", other);
    reproduce(config(), out.string(), "test");
    EXPECT_EQ(cases_csv(), lines);
}

TEST_F(ReproduceTest, TablesOnlyEvaluatesNothingAndShowsWhatIsPending) {
    fs::path out = dir_->path() / "tables-only";
    nlohmann::json empty = reproduce(config(), out.string(), "test", /*evaluate=*/false);
    EXPECT_FALSE(fs::exists(out / "runs/test-indist-x4/pugcn-x4/cases.csv"));
    EXPECT_TRUE(fs::exists(out / "tables.md"));
    const nlohmann::json& cell = row(empty.at("table1"), "PU-GCN").at("cells")[0];
    EXPECT_EQ(cell.at("missing"), "not evaluated yet");
    bool listed = false;
    for (const auto& note : empty.at("missing"))
        listed |= note.get<std::string>() ==
                  "not evaluated yet (`--tables-only`): runs/test-indist-x4/pugcn-x4";
    EXPECT_TRUE(listed);

    nlohmann::json full = reproduce(config(), out.string(), "test");
    nlohmann::json again = reproduce(config(), out.string(), "test", /*evaluate=*/false);
    EXPECT_EQ(again.at("table1"), full.at("table1"));
    EXPECT_EQ(again.at("table2"), full.at("table2"));
}

TEST_F(ReproduceTest, ACellThatFailsOnItsInputKeepsItsErrorAndIsNotPending) {
    // Without a second GT sample there is no sampling floor for test-scans.
    fs::path cases =
        fs::path(config_->at("dataset_dir").get<std::string>()) / "cases" / "test-scans" / "x4";
    // The dataset is shared by the suite's tests: the files are put back afterwards, so that
    // the tests pass in any order and in one process.
    struct PutBack {
        std::vector<fs::path> moved;
        ~PutBack() {
            for (const fs::path& file : moved) fs::rename(file.string() + ".away", file);
        }
    } put_back;
    for (const auto& entry : fs::directory_iterator(cases))
        if (entry.is_directory() && fs::exists(entry.path() / "gt_alt.ply")) {
            fs::rename(entry.path() / "gt_alt.ply",
                       (entry.path() / "gt_alt.ply").string() + ".away");
            put_back.moved.push_back(entry.path() / "gt_alt.ply");
        }
    ASSERT_GT(put_back.moved.size(), 0u);
    fs::path out = dir_->path() / "floorless";
    auto floor_cell = [](const nlohmann::json& tables) {
        return row(tables.at("table1"), "sampling floor (2nd GT sample)").at("cells")[2];
    };
    nlohmann::json full = reproduce(config(), out.string(), "test");
    const std::string error = floor_cell(full).at("missing");
    EXPECT_NE(error.find("gt_alt.ply"), std::string::npos) << error;
    EXPECT_TRUE(fs::exists(out / "runs/test-scans-x4/floor/error.json"));

    nlohmann::json again = reproduce(config(), out.string(), "test", /*evaluate=*/false);
    EXPECT_EQ(floor_cell(again).at("missing"), error);
    for (const auto& note : again.at("missing"))
        EXPECT_EQ(note.get<std::string>().find("not evaluated yet"), std::string::npos) << note;
}

TEST_F(ReproduceTest, NoiseBackbonesLimitTableTwoToTheBackbonesListed) {
    fs::path out = dir_->path() / "noise-rows";
    ReproduceConfig c = config();
    nlohmann::json all = reproduce(c, out.string(), "test");
    EXPECT_NO_THROW(row(all.at("table2"), "PU-GCN"));

    c.noise_backbones = {"dispu"};
    nlohmann::json limited = reproduce(c, out.string(), "test");
    EXPECT_THROW(row(limited.at("table2"), "PU-GCN"), std::runtime_error);
    EXPECT_NO_THROW(row(limited.at("table2"), "midpoint baseline"));
    EXPECT_EQ(limited.at("table1"), all.at("table1"));  // other tables keep their rows
    EXPECT_NE(test::read_file((out / "tables.md").string())
                  .find("Rows only for Dis-PU (`noise_backbones`"),
              std::string::npos);
}

std::vector<std::string> evaluated_cells(const fs::path& log) {
    std::vector<std::string> cells;
    std::ifstream in(log);
    const std::string marker = "] evaluating ";
    for (std::string line; std::getline(in, line);)
        if (size_t at = line.find(marker); at != std::string::npos)
            cells.push_back(line.substr(at + marker.size()));
    return cells;
}

TEST_F(ReproduceTest, TwoProcessesOnOneOutputShareTheCellsAndAStaleLockIsTakenOver) {
    fs::path out = dir_->path() / "shared", config_file = dir_->path() / "shared.json";
    std::ofstream(config_file) << config_->dump();
    // A lock left behind by a process of this host that has ended.
    FILE* shell = popen("echo $$", "r");
    ASSERT_NE(shell, nullptr);
    long dead_pid = 0;
    ASSERT_EQ(fscanf(shell, "%ld", &dead_pid), 1);
    pclose(shell);
    char host[256] = {};
    gethostname(host, sizeof host - 1);
    fs::create_directories(out / "runs/test-indist-x4");
    std::ofstream(out / "runs/test-indist-x4/pugcn-x4.lock") << host << " " << dead_pid;

    const std::string pumeta = test::built_program("pumeta");
    ASSERT_FALSE(pumeta.empty());
    auto command = [&](int i) {
        return fmt::format("{} --threads 1 reproduce --config {} --budget quick -o {} 2> {}",
                           pumeta, config_file.string(), out.string(),
                           (dir_->path() / fmt::format("shared{}.log", i)).string());
    };
    std::string both = command(1) + " & first=$!; " + command(2) +
                       "; second=$?; wait $first; exit $(( $? | second ))";
    ASSERT_EQ(std::system(both.c_str()), 0)
        << test::read_file((dir_->path() / "shared1.log").string())
        << test::read_file((dir_->path() / "shared2.log").string());

    // Every cell was evaluated by exactly one of the two processes, and none is left locked.
    std::vector<std::string> one = evaluated_cells(dir_->path() / "shared1.log");
    std::vector<std::string> two = evaluated_cells(dir_->path() / "shared2.log");
    std::multiset<std::string> all(one.begin(), one.end());
    all.insert(two.begin(), two.end());
    int64_t cells = 0;
    for (const auto& entry : fs::recursive_directory_iterator(out / "runs")) {
        EXPECT_NE(entry.path().extension(), ".lock") << entry.path();
        if (entry.path().filename() != "spec.json") continue;
        ++cells;
        std::string key = fs::relative(entry.path().parent_path(), out / "runs").string();
        EXPECT_EQ(all.count(key), 1u) << key;
    }
    EXPECT_EQ(int64_t(all.size()), cells);
    EXPECT_TRUE(std::count(all.begin(), all.end(), "test-indist-x4/pugcn-x4"));
    EXPECT_NE(test::read_file((out / "tables.md").string()).find("## Table VI:"),
              std::string::npos);
}

TEST(ReproduceConfig, BudgetsOverrideFieldsAndMistakesAreInputErrors) {
    nlohmann::json j = {
        {"main_ratio", 4},
        {"budgets", {{"quick", {{"max_cases", 3}}}, {"full", nlohmann::json::object()}}}};
    EXPECT_EQ(ReproduceConfig::from_json(j, "quick").max_cases, 3);
    EXPECT_EQ(ReproduceConfig::from_json(j, "full").max_cases, 0);
    EXPECT_EQ(ReproduceConfig::from_json(j, "full").main_ratio, 4);
    EXPECT_THROW(ReproduceConfig::from_json(j, "huge"), InputError);
    EXPECT_THROW(ReproduceConfig::from_json({{"main_ratios", 4}}, "full"), InputError);
    EXPECT_THROW(ReproduceConfig::from_json({{"main_ratio", "8"}}, "full"), InputError);
    EXPECT_THROW(ReproduceConfig::from_json({{"tta_unit", "scene"}}, "full"), InputError);

    // A step size for one ratio wins over the backbone's.
    ReproduceConfig lrs = ReproduceConfig::from_json(
        {{"tta_lr_without_meta", {{"pugcn", 0.03}, {"pugcn-x8", 0.01}}}}, "full");
    EXPECT_EQ(lrs.tta_lr_for("pugcn", 4), 0.03);
    EXPECT_EQ(lrs.tta_lr_for("pugcn", 8), 0.01);
    EXPECT_FALSE(lrs.tta_lr_for("dispu", 8).has_value());
}

TEST(ReproduceConfig, TheShippedConfigRoundTripsThroughJson) {
    std::ifstream in(std::string(PUMETA_SOURCE_DIR) + "/configs/reproduce.json");
    ASSERT_TRUE(in) << "configs/reproduce.json";
    ReproduceConfig full = ReproduceConfig::from_json(nlohmann::json::parse(in), "full");
    EXPECT_FALSE(full.external_baselines.empty());
    EXPECT_FALSE(full.zero_shot.backbones.empty());
    nlohmann::json written = full.to_json();
    written.erase("budget");
    ReproduceConfig back = ReproduceConfig::from_json(written, "full");
    EXPECT_EQ(back.to_json(), full.to_json());

    std::ifstream pugan_in(std::string(PUMETA_SOURCE_DIR) + "/configs/reproduce-pugan.json");
    ASSERT_TRUE(pugan_in) << "configs/reproduce-pugan.json";
    ReproduceConfig pugan = ReproduceConfig::from_json(nlohmann::json::parse(pugan_in), "full");
    EXPECT_FALSE(pugan.paper_tables);
    ASSERT_EQ(pugan.benchmarks.size(), 1u);
    EXPECT_EQ(pugan.benchmarks[0].ratios, (std::vector<int64_t>{4, 16}));
    nlohmann::json pugan_written = pugan.to_json();
    pugan_written.erase("budget");
    EXPECT_EQ(ReproduceConfig::from_json(pugan_written, "full").to_json(), pugan.to_json());

    EXPECT_THROW(ReproduceConfig::from_json({{"zero_shot", {{"backbone", {"pugcn"}}}}}, "full"),
                 InputError);
    EXPECT_THROW(ReproduceConfig::from_json({{"external_baselines", {{{"label", "x"}}}}}, "full"),
                 InputError);
}

}  // namespace
}  // namespace pumeta
