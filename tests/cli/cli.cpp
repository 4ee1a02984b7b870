// The CLI contract: exit codes, one-line errors naming the file, --json forms, no partial
// output files.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include "pumeta/data/patch_set.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/train/trainer.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

bool one_line(const std::string& text) {
    return !text.empty() && text.find('\n') == text.size() - 1;
}

TEST(Cli, MissingFileIsExitTwoWithOneLineNamingTheFile) {
    test::TempDir dir;
    auto r = test::run_cli({"info", dir.file("nope.ply")});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_TRUE(one_line(r.err)) << r.err;
    EXPECT_NE(r.err.find("nope.ply"), std::string::npos) << r.err;
}

TEST(Cli, BadInputsGiveExitTwoAndNoOutputFile) {
    test::TempDir dir;
    test::write_file(dir.file("empty.ply"), "");
    test::write_file(dir.file("cloud.laz"), "LASF");
    test::write_file(dir.file("cloud.abc"), "1 2 3\n");
    test::write_file(dir.file("nan.xyz"), "0 0 0\nnan 1 2\n1 1 1\n");
    test::write_file(dir.file("lies.ply"),
                     "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
                     "property float z\nend_header\n0 0 0\n1 1 1\n");
    for (const char* name : {"empty.ply", "cloud.laz", "cloud.abc", "nan.xyz", "lies.ply"}) {
        std::string out = dir.file(std::string(name) + ".out.ply");
        auto r = test::run_cli({"convert", dir.file(name), "-o", out});
        EXPECT_EQ(r.exit_code, 2) << name << ": " << r.err;
        EXPECT_TRUE(one_line(r.err)) << name << ": " << r.err;
        EXPECT_NE(r.err.find(name), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(out)) << name;
    }
    // Dropping invalid points on request works and says how many.
    auto r =
        test::run_cli({"convert", dir.file("nan.xyz"), "-o", dir.file("ok.ply"), "--drop-invalid"});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(read_point_cloud(dir.file("ok.ply")).size(), 2);
}

TEST(Cli, NumericOptionsAreValidatedWithOneLine) {
    test::TempDir dir;
    write_point_cloud(dir.file("in.ply"), {uniform_random_points(40, 1)});
    const std::string in = dir.file("in.ply"), out = dir.file("out.ply");
    const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
        {{"upsample", in, "-o", out, "--method", "midpoint", "--ratio", "0"}, "--ratio"},
        {{"upsample", in, "-o", out, "--method", "midpoint", "--ratio", "-1"}, "--ratio"},
        {{"upsample", in, "-o", out, "--method", "midpoint", "--ratio", "2.5"}, "--ratio"},
        {{"upsample", in, "-o", out, "--tta-steps", "-5"}, "--tta-steps"},
        {{"upsample", in, "-o", out, "--tta-lr", "nan"}, "--tta-lr"},
        {{"upsample", in, "-o", out, "--tta-lr", "-0.1"}, "--tta-lr"},
        {{"upsample", in, "-o", out, "--seed", "-3"}, "--seed"},
        {{"upsample", in, "-o", out, "--batch-patches", "0"}, "--batch-patches"},
        {{"upsample", in, "-o", out, "--select", "random"}, "--select"},
        {{"--threads", "0", "upsample", in, "-o", out}, "--threads"},
        {{"sample", in, "-n", "0", "-o", out}, "--count"},
        {{"render", in, "-o", dir.file("a.png"), "--point-radius", "inf"}, "--point-radius"},
    };
    for (const auto& [args, option] : cases) {
        auto r = test::run_cli(args);
        const std::string shown = args[args.size() - 2] + " " + args.back();
        EXPECT_EQ(r.exit_code, 2) << shown << ": " << r.err;
        EXPECT_TRUE(one_line(r.err)) << shown << ": " << r.err;
        EXPECT_EQ(r.err.rfind("pumeta: error: ", 0), 0u) << r.err;
        EXPECT_NE(r.err.find(option), std::string::npos) << r.err;
        EXPECT_LT(r.err.size(), 200u) << r.err;  // no 310-digit range
        EXPECT_FALSE(fs::exists(out)) << shown;
    }
}

// The same input and seed give the same bytes on any thread count, also with an OpenBLAS
// kernel whose multi-threaded products round differently with the thread count (Haswell's,
// where the CPU has it), with test-time adaptation and on clouds large enough for either
// final selection: an even one (Poisson disk) takes the ownership merge, an irregular one
// (uniformly random points) the pruned FPS.
TEST(Cli, UpsampleGivesTheSameBytesWithOneOrTwoThreads) {
    test::TempDir dir;
    write_point_cloud(dir.file("small.ply"), {sample_uniform(generate_shape(3), 2048, 1).points});
    write_point_cloud(dir.file("large.ply"), {sample_uniform(generate_shape(3), 12000, 2).points});
    write_point_cloud(dir.file("large-even.ply"),
                      {sample_poisson_disk(generate_shape(3), 12000, 2).points});
    std::vector<std::string> kernels = {"default"};
    if (test::read_file("/proc/cpuinfo").find(" avx2") != std::string::npos)
        kernels.push_back("Haswell");
    const std::string meta = test::source_dir() + "/models/pugcn-x4-meta.pt";
    for (const std::string& kernel : kernels)
        for (const std::string& input : {"small", "large", "large-even"}) {
            std::string outputs[2];
            for (int threads : {1, 2}) {
                outputs[threads - 1] = dir.file(input + std::to_string(threads) + ".ply");
                std::vector<std::string> args = {"-u", "OPENBLAS_CORETYPE"};
                if (kernel != "default") args = {"OPENBLAS_CORETYPE=" + kernel};
                for (const std::string& arg :
                     {test::cli_path(), std::string("--threads"), std::to_string(threads),
                      std::string("upsample"), dir.file(input + ".ply"), std::string("-o"),
                      outputs[threads - 1], std::string("--model"), meta,
                      std::string("--tta-steps"), std::string("2")})
                    args.push_back(arg);
                auto r = test::run_command("env", args);
                ASSERT_EQ(r.exit_code, 0) << r.err;
            }
            EXPECT_EQ(test::read_file(outputs[0]), test::read_file(outputs[1]))
                << kernel << " kernel, " << input << " input";
        }
}

/// Width and height of a PNG file, from its IHDR chunk.
std::pair<int, int> png_size(const std::string& path) {
    const std::string bytes = test::read_file(path);
    auto be32 = [&](size_t at) {
        return int((uint8_t(bytes.at(at)) << 24) | (uint8_t(bytes.at(at + 1)) << 16) |
                   (uint8_t(bytes.at(at + 2)) << 8) | uint8_t(bytes.at(at + 3)));
    };
    return {be32(16), be32(20)};
}

// An error picture (render --error-to) carries its scale: a colour bar and caption under the
// render, which a plain render has not.
TEST(Cli, AnErrorPictureCarriesItsColourBar) {
    test::TempDir dir;
    const std::string pred = dir.file("pred.xyz"), gt = dir.file("gt.xyz");
    write_point_cloud(pred, {test::sphere_points(400, 1), {}, {}});
    write_point_cloud(gt, {test::sphere_points(1600, 2), {}, {}});
    const auto plain =
        test::run_cli({"render", pred, "-o", dir.file("plain.png"), "--size", "200"});
    ASSERT_EQ(plain.exit_code, 0) << plain.err;
    EXPECT_EQ(png_size(dir.file("plain.png")), std::make_pair(200, 200));
    const auto error = test::run_cli(
        {"render", pred, "--error-to", gt, "-o", dir.file("error.png"), "--size", "200"});
    ASSERT_EQ(error.exit_code, 0) << error.err;
    const auto [width, height] = png_size(dir.file("error.png"));
    EXPECT_EQ(width, 200);
    EXPECT_GT(height, 230);
}

TEST(Cli, AConfigNumberOutOfRangeIsAOneLineInputError) {
    test::TempDir dir;
    test::write_file(dir.file("c.json"), "{\"steps\": 1e4308}");
    auto r = test::run_cli({"train", "--config", dir.file("c.json")});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_TRUE(one_line(r.err)) << r.err;
    EXPECT_NE(r.err.find("c.json: invalid JSON"), std::string::npos) << r.err;
}

TEST(Cli, MetricsJsonHasTheContractKeys) {
    test::TempDir dir;
    at::Tensor gt = uniform_random_points(200, 1);
    at::Tensor pred = gt + 0.01 * uniform_random_points(200, 2);
    write_point_cloud(dir.file("gt.ply"), {gt});
    write_point_cloud(dir.file("pred.ply"), {pred});
    auto r = test::run_cli({"metrics", dir.file("pred.ply"), dir.file("gt.ply"), "--json"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto j = nlohmann::json::parse(r.out);
    for (const char* key : {"cd", "hd", "hd_legacy", "psnr", "p2f", "n_pred", "n_gt"})
        EXPECT_TRUE(j.contains(key)) << key;
    EXPECT_TRUE(j["p2f"].is_null());
    EXPECT_EQ(j["n_pred"], 200);
    EXPECT_GT(j["cd"].get<double>(), 0.0);
}

TEST(Cli, InfoJsonAndSample) {
    test::TempDir dir;
    // A unit cube as OFF.
    test::write_file(dir.file("cube.off"),
                     "OFF\n8 6 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
                     "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 2 3 7 6\n4 1 2 6 5\n4 0 4 7 3\n");
    auto info = test::run_cli({"info", dir.file("cube.off"), "--json"});
    ASSERT_EQ(info.exit_code, 0) << info.err;
    auto j = nlohmann::json::parse(info.out);
    EXPECT_EQ(j["points"], 8);
    EXPECT_EQ(j["faces"], 12);
    auto sample = test::run_cli(
        {"sample", dir.file("cube.off"), "-n", "500", "--seed", "3", "-o", dir.file("s.ply")});
    ASSERT_EQ(sample.exit_code, 0) << sample.err;
    EXPECT_EQ(read_point_cloud(dir.file("s.ply")).size(), 500);
    // What upsample takes a cloud for: an even sample of the cube's surface.
    auto cloud_info = test::run_cli({"info", dir.file("s.ply"), "--json"});
    ASSERT_EQ(cloud_info.exit_code, 0) << cloud_info.err;
    auto c = nlohmann::json::parse(cloud_info.out);
    EXPECT_EQ(c["input_kind"], "sampled");
    EXPECT_GT(c["spacing_spread"].get<double>(), 1.0);
    EXPECT_GE(c["surface_thickness"].get<double>(), 0.0);
    // Noise-free samples of flat faces: on a quadric (kExactRoughness = 0.03).
    EXPECT_LT(c["surface_roughness"].get<double>(), 0.03);
    auto text = test::run_cli({"info", dir.file("s.ply")});
    EXPECT_NE(text.out.find("taken for: sampled"), std::string::npos) << text.out;
    EXPECT_NE(text.out.find("surface roughness"), std::string::npos) << text.out;
    // More points than a tiny cloud has is a clear error, not a crash.
    auto too_many =
        test::run_cli({"sample", dir.file("cube.off"), "-n", "0", "-o", dir.file("t.ply")});
    EXPECT_EQ(too_many.exit_code, 2);
}

TEST(Cli, PuDenseUpsamplesAtAnyRatioAndRatioBoundModelsSayWhy) {
    test::TempDir dir;
    save_checkpoint(dir.file("pudense.pt"), *make_backbone({{"backbone", "pudense"},
                                                            {"ratio", 8},
                                                            {"channels", {4, 4, 8, 8, 8}},
                                                            {"resolution", 4},
                                                            {"patch_size", 32},
                                                            {"seed", 3}}));
    save_checkpoint(dir.file("pugcn.pt"), *make_backbone(test::tiny_pugcn_config(4, 1)));
    write_point_cloud(dir.file("in.ply"), {uniform_random_points(60, 1)});
    auto info = test::run_cli({"info", dir.file("pudense.pt"), "--json"});
    ASSERT_EQ(info.exit_code, 0) << info.err;
    EXPECT_EQ(nlohmann::json::parse(info.out)["any_ratio"], true);
    auto r = test::run_cli({"upsample", dir.file("in.ply"), "-o", dir.file("out.ply"), "--model",
                            dir.file("pudense.pt"), "--ratio", "3"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(read_point_cloud(dir.file("out.ply")).size(), 180);

    info = test::run_cli({"info", dir.file("pugcn.pt"), "--json"});
    EXPECT_EQ(nlohmann::json::parse(info.out)["any_ratio"], false);
    r = test::run_cli({"upsample", dir.file("in.ply"), "-o", dir.file("out3.ply"), "--model",
                       dir.file("pugcn.pt"), "--ratio", "3"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("not a power of the model's ratio 4"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out3.ply")));
}

TEST(Cli, UnknownDeviceIsAnInputError) {
    test::TempDir dir;
    write_point_cloud(dir.file("in.ply"), {uniform_random_points(50, 1)});
    auto r = test::run_cli(
        {"upsample", dir.file("in.ply"), "-o", dir.file("out.ply"), "--device", "tpu"});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out.ply")));
}

TEST(Cli, TrainStoppedBySigtermSavesACheckpointAndExits130) {
    test::TempDir dir;
    PatchSet set;
    set.ratio = 4;
    set.patch_points = 16;
    set.points = uniform_random_points(200, 5);
    set.offsets = at::tensor({int64_t{0}, int64_t{200}});
    set.seeds = at::tensor(std::vector<int64_t>{0, 0, 0, 99}).view({2, 2});
    set.ids = {"a"};
    save_patch_set(dir.file("train.tensors"), set);
    TrainConfig config;
    config.backbone = test::tiny_pugcn_config(4, 11);
    config.train_data = dir.file("train.tensors");
    config.run_dir = dir.file("run");
    config.batch_size = 2;
    config.steps = 1000000;  // only the signal ends it
    config.log_every = 1;
    std::ofstream(dir.file("train.json")) << config.to_json().dump();
    // Start training, wait for its first log line, then send SIGTERM as a scheduler would.
    const std::string script =
        "\"$0\" train --config \"$1\" >/dev/null 2>\"$2\" & pid=$!; i=0; "
        "while [ ! -s \"$3\" ] && [ $i -lt 1200 ]; do sleep 0.1; i=$((i+1)); done; "
        "kill -TERM $pid; wait $pid; echo $?";
    auto r = test::run_command("/bin/sh",
                               {"-c", script, test::built_program("pumeta"), dir.file("train.json"),
                                dir.file("err"), dir.file("run/log.jsonl")});
    EXPECT_EQ(r.out, "130\n") << test::read_file(dir.file("err"));
    EXPECT_NE(test::read_file(dir.file("err")).find("interrupted at step"), std::string::npos)
        << test::read_file(dir.file("err"));
    EXPECT_TRUE(fs::exists(dir.file("run/state.ckpt")));
}

TEST(Cli, EvalWithoutAModelTakesTheShippedModelForTheCasesRatio) {
    test::TempDir dir;
    test::make_tiny_reproduction(dir.path());
    // The same cases relabelled as 8x (the metrics do not depend on the label).
    const fs::path x4 = dir.file("data/cases/test-indist/x4");
    const fs::path x8 = dir.file("data/cases/test-indist/x8");
    fs::copy(x4, x8, fs::copy_options::recursive);
    nlohmann::json index = nlohmann::json::parse(test::read_file((x8 / "cases.json").string()));
    index["ratio"] = 8;
    test::write_file((x8 / "cases.json").string(), index.dump());
    fs::create_directories(dir.file("shipped"));
    save_checkpoint(dir.file("shipped/pugcn-x4.pt"), *make_backbone(test::tiny_pugcn_config(4, 1)));
    save_checkpoint(dir.file("shipped/pugcn-x8.pt"), *make_backbone(test::tiny_pugcn_config(8, 2)));
    test::write_file(dir.file("shipped/defaults.json"), R"({"family": "pugcn"})");
    setenv("PUMETA_MODELS", dir.file("shipped").c_str(), 1);
    auto r = test::run_cli({"--threads", "1", "eval", "--cases", x8.string(), "--max-cases", "1",
                            "-o", dir.file("out")});
    unsetenv("PUMETA_MODELS");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(test::read_file(dir.file("out/summary.json")))["ratio"], 8);
    // A --ratio that contradicts the cases is an input error.
    r = test::run_cli({"eval", "--cases", x8.string(), "--ratio", "4", "-o", dir.file("out4")});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("ratio 8"), std::string::npos) << r.err;
}

TEST(Cli, OracleAdaptationIsAnEvalDiagnosticAndAdamStepsRun) {
    test::TempDir dir;
    test::make_tiny_reproduction(dir.path());
    const std::string cases = dir.file("data/cases/test-indist/x4");
    const std::string model = dir.file("models/pugcn-x4.pt");
    auto eval = [&](const std::string& out, std::vector<std::string> extra) {
        std::vector<std::string> args = {"--threads", "1",       "eval",       "--model",
                                         model,       "--cases", cases,        "--max-cases",
                                         "2",         "-o",      dir.file(out)};
        args.insert(args.end(), extra.begin(), extra.end());
        auto r = test::run_cli(args);
        EXPECT_EQ(r.exit_code, 0) << r.err;
        return nlohmann::json::parse(test::read_file(dir.file(out + "/summary.json")));
    };
    auto plain = eval("plain", {"--tta-steps", "0"});
    auto oracle = eval("oracle", {"--tta-steps", "3", "--tta-lr", "0.05", "--tta-unit", "oracle"});
    // The untrained model fitted to the ground truth comes closer to it.
    EXPECT_LT(oracle["cd"]["mean"].get<double>(), plain["cd"]["mean"].get<double>());
    EXPECT_LT(oracle["tta"]["loss_after"]["mean"].get<double>(),
              oracle["tta"]["loss_before"]["mean"].get<double>());
    auto adam = eval("adam", {"--tta-steps", "3", "--tta-lr", "1e-3", "--tta-optimizer", "adam"});
    EXPECT_LT(adam["tta"]["loss_after"]["mean"].get<double>(),
              adam["tta"]["loss_before"]["mean"].get<double>());

    // `upsample` has no ground truth: a one-line input error and no output.
    write_point_cloud(dir.file("in.ply"), {uniform_random_points(60, 1)});
    auto r = test::run_cli({"upsample", dir.file("in.ply"), "-o", dir.file("out.ply"), "--model",
                            model, "--tta-steps", "2", "--tta-lr", "0.1", "--tta-unit", "oracle"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_TRUE(one_line(r.err)) << r.err;
    EXPECT_NE(r.err.find("oracle"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir.file("out.ply")));
}

TEST(Cli, ReproduceQuickWritesEveryTableAndABadConfigIsAOneLineError) {
    test::TempDir dir;
    std::ofstream(dir.file("reproduce.json")) << test::make_tiny_reproduction(dir.path()).dump();
    auto r = test::run_cli({"--threads", "1", "reproduce", "--config", dir.file("reproduce.json"),
                            "--budget", "quick", "-o", dir.file("results")});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string md = test::read_file(dir.file("results/tables.md"));
    for (const char* title : {"## Table I:", "## Table II:", "## Table III:", "## Table IV:",
                              "## Table V:", "## Table VI:"})
        EXPECT_NE(md.find(title), std::string::npos) << title;
    EXPECT_TRUE(fs::exists(dir.file("results/tables.json")));

    test::write_file(dir.file("broken.json"), "{\"sets\": [");
    auto bad = test::run_cli(
        {"reproduce", "--config", dir.file("broken.json"), "-o", dir.file("results2")});
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_TRUE(one_line(bad.err)) << bad.err;
    EXPECT_NE(bad.err.find("broken.json"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace pumeta
