// The public benchmarks' formats end to end through the binary: `pumeta eval --benchmark` on
// miniature PU-GAN and PU1K test folders (scores checked against a brute-force computation
// here), the same on three of the public PU-GAN test meshes when ../shared holds them, `train`
// and `meta-train` on an HDF5 patch file, and one-line errors for bad input.
#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "geometry/mesh_oracles.h"
#include "metrics/metric_oracles.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"
#include "pumeta/train/trainer.h"
#include "support/hdf5_files.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

/// The cube [-1, 1]³ as 12 triangles.
TriangleMesh cube() {
    std::vector<float> v;
    for (int i = 0; i < 8; ++i)
        for (int axis = 0; axis < 3; ++axis) v.push_back((i >> axis) & 1 ? 1.f : -1.f);
    const std::vector<int64_t> f = {0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1,
                                    2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3};
    return {at::tensor(v, at::kFloat).view({8, 3}).clone(),
            at::tensor(f, at::kLong).view({12, 3}).clone()};
}

/// A PU-GAN test folder under `root`: objects "cube" (with its mesh in original_meshes/) and
/// "sphere" (without one), 256 input and 1024 GT points. `nested`: PU1K's input_256/input_256/.
void make_test_folder(const fs::path& root, bool nested = false) {
    const fs::path input = nested ? root / "input_256" / "input_256" : root / "input_256";
    const fs::path gt = nested ? root / "gt_1024" / "gt_1024" : root / "gt_1024";
    fs::create_directories(input);
    fs::create_directories(gt);
    fs::create_directories(root / "original_meshes");
    const TriangleMesh mesh = cube();
    write_point_cloud((input / "cube.xyz").string(), {sample_uniform(mesh, 256, 1).points, {}, {}});
    write_point_cloud((gt / "cube.xyz").string(), {sample_uniform(mesh, 1024, 2).points, {}, {}});
    write_mesh((root / "original_meshes" / "cube.off").string(), mesh);
    write_point_cloud((input / "sphere.xyz").string(), {test::sphere_points(256, 3), {}, {}});
    write_point_cloud((gt / "sphere.xyz").string(), {test::sphere_points(1024, 4), {}, {}});
}

at::Tensor own_unit_sphere(const at::Tensor& points) {
    at::Tensor p = points.to(at::kDouble);
    p = p - p.mean(0);
    return p / p.norm(2, 1).max();
}

TEST(CliBenchmark, EvalScoresEachObjectWithThePublishedProtocol) {
    test::TempDir dir;
    make_test_folder(dir.path() / "test");
    auto r = test::run_cli({"--threads", "1", "eval", "--benchmark", "pugan", "--data",
                            dir.file("test"), "--method", "input", "-o", dir.file("out")});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto rows = test::read_csv(dir.file("out/cases.csv"));
    ASSERT_EQ(rows.size(), 3u);
    EXPECT_EQ(rows[0][0], "object");
    EXPECT_EQ(rows[1][0], "cube");
    EXPECT_EQ(rows[2][0], "sphere");
    double cd_sum = 0;
    for (size_t i = 1; i < rows.size(); ++i) {
        const auto& row = rows[i];
        ASSERT_EQ(row.size(), 10u);
        EXPECT_EQ(row[1], "256");
        EXPECT_EQ(row[2], "256");  // method "input": the input itself
        EXPECT_EQ(row[3], "1024");
        // The input against its GT, each normalised here, by brute force.
        const at::Tensor input =
            read_point_cloud(dir.file("test/input_256/" + row[0] + ".xyz")).points;
        const at::Tensor gt = read_point_cloud(dir.file("test/gt_1024/" + row[0] + ".xyz")).points;
        const at::Tensor p = own_unit_sphere(input), g = own_unit_sphere(gt);
        const auto forward = test::brute_force_sq_distances(p, g);
        const auto backward = test::brute_force_sq_distances(g, p);
        const double cd = (test::mean(forward) + test::mean(backward)) * 1e3;
        const double hd = std::sqrt(std::max(test::max(forward), test::max(backward))) * 1e3;
        EXPECT_NEAR(std::stod(row[4]), cd, 1e-5 * cd) << row[0];
        EXPECT_NEAR(std::stod(row[5]), hd, 1e-5 * hd) << row[0];
        cd_sum += std::stod(row[4]);
    }
    // The cube's input lies on its mesh; the sphere has none.
    EXPECT_LT(std::stod(rows[1][7]), 1e-2);
    EXPECT_EQ(rows[2][7], "");
    const auto summary = nlohmann::json::parse(test::read_file(dir.file("out/summary.json")));
    EXPECT_EQ(summary["benchmark"], "pugan");
    EXPECT_EQ(summary["ratio"], 4);
    EXPECT_EQ(summary["input_points"], 256);
    EXPECT_EQ(summary["objects"], 2);
    EXPECT_EQ(summary["objects_with_mesh"], 1);
    EXPECT_EQ(summary["p2f_points"], 256);
    EXPECT_NEAR(summary["cd_1e3"].get<double>(), cd_sum / 2, 1e-6 * cd_sum);
    EXPECT_TRUE(summary["p2f_1e3"].is_number());
    EXPECT_NE(summary["note"].get<std::string>().find("1 of 2"), std::string::npos);
    EXPECT_NE(summary["protocol"].get<std::string>().find("own unit sphere"), std::string::npos);
}

/// Mean distance of `points` to the mesh, by brute force over every face (exact
/// point-to-triangle distances, mesh_oracles.h).
double brute_force_p2f(const at::Tensor& points, const TriangleMesh& mesh) {
    const at::Tensor p = points.to(at::kDouble).contiguous();
    const at::Tensor corners =
        mesh.vertices.to(at::kDouble).index_select(0, mesh.faces.flatten()).contiguous();
    const double* c = corners.data_ptr<double>();
    auto a = p.accessor<double, 2>();
    double sum = 0;
    for (int64_t i = 0; i < p.size(0); ++i) {
        const test::Vec3 q{a[i][0], a[i][1], a[i][2]};
        double best = std::numeric_limits<double>::infinity();
        for (int64_t f = 0; f < mesh.num_faces(); ++f) {
            const double* t = c + 9 * f;
            best =
                std::min(best, test::point_triangle_sq_distance(
                                   q, {t[0], t[1], t[2]}, {t[3], t[4], t[5]}, {t[6], t[7], t[8]}));
        }
        sum += std::sqrt(best);
    }
    return sum / static_cast<double>(p.size(0));
}

// The benchmark command on real data: three of the 21 public PU-GAN test meshes (evaluation
// only; skipped without ../shared), the midpoint baseline and a shipped model, every score
// recomputed here from the saved predictions by brute force: nearest neighbours over all
// pairs, exact point-to-triangle distances over all faces, P2F in the mesh's own coordinates.
TEST(CliBenchmark, PublicPuganMeshesScoreAsAnIndependentComputation) {
    const fs::path shared = test::pugan_benchmark_dir();
    if (!test::have_pugan_benchmark()) GTEST_SKIP() << "no " << shared.string();
    test::TempDir dir;
    const fs::path data = test::pugan_benchmark_subset(dir, {"camel", "fandisk", "star"});
    const std::string model = test::source_dir() + "/models/pugcn-x4.pt";
    for (const std::vector<std::string>& method : {std::vector<std::string>{"--method", "midpoint"},
                                                   std::vector<std::string>{"--model", model}}) {
        const std::string out = dir.file("out-" + method[0].substr(2));
        std::vector<std::string> args = {
            "--threads",   "1",       "eval", "--benchmark",        "pugan", "--data",
            data.string(), "--ratio", "4",    "--save-predictions", "-o",    out};
        args.insert(args.end(), method.begin(), method.end());
        const auto r = test::run_cli(args);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        const auto rows = test::read_csv(out + "/cases.csv");
        ASSERT_EQ(rows.size(), 4u) << method[1];
        double p2f_sum = 0;
        for (size_t i = 1; i < rows.size(); ++i) {
            const std::string& name = rows[i][0];
            const at::Tensor pred = read_point_cloud(out + "/pred/" + name + ".xyz").points;
            const at::Tensor gt =
                read_point_cloud((shared / "gt_8192" / (name + ".xyz")).string()).points;
            const at::Tensor input =
                read_point_cloud((shared / "input_2048" / (name + ".xyz")).string()).points;
            const TriangleMesh mesh =
                read_mesh((shared / "original_meshes" / (name + ".off")).string());
            // Exactly 8,192 points, no position twice (the midpoint's old padding repeated one
            // point hundreds of times).
            ASSERT_EQ(pred.size(0), 8192) << method[1] << " " << name;
            EXPECT_EQ(count_distinct_points(pred), 8192) << method[1] << " " << name;
            const at::Tensor p = own_unit_sphere(pred), g = own_unit_sphere(gt);
            const double cd = (test::mean(test::brute_force_sq_distances(p, g)) +
                               test::mean(test::brute_force_sq_distances(g, p))) *
                              1e3;
            EXPECT_NEAR(std::stod(rows[i][4]), cd, 1e-3 * cd) << method[1] << " " << name;
            const double p2f = brute_force_p2f(pred, mesh) * 1e3;
            EXPECT_NEAR(std::stod(rows[i][7]), p2f, 1e-3 * p2f) << method[1] << " " << name;
            p2f_sum += p2f * static_cast<double>(pred.size(0));
            // Both methods are closer to the ground truth than their input.
            const at::Tensor q = own_unit_sphere(input);
            const double input_cd = (test::mean(test::brute_force_sq_distances(q, g)) +
                                     test::mean(test::brute_force_sq_distances(g, q))) *
                                    1e3;
            EXPECT_LT(cd, input_cd) << method[1] << " " << name;
        }
        const auto summary = nlohmann::json::parse(test::read_file(out + "/summary.json"));
        const double pooled = p2f_sum / (3 * 8192);
        EXPECT_NEAR(summary["p2f_1e3"].get<double>(), pooled, 1e-3 * pooled) << method[1];
        EXPECT_NE(summary["protocol"].get<std::string>().find("mesh's own coordinates"),
                  std::string::npos);
    }
}

TEST(CliBenchmark, EvalRunsTheMidpointBaselineAndANetworkOnPu1kNesting) {
    test::TempDir dir;
    make_test_folder(dir.path() / "pu1k", /*nested=*/true);
    // A second ground truth makes the ratio a choice.
    fs::create_directories(dir.path() / "pu1k" / "gt_2048");
    auto r = test::run_cli({"eval", "--benchmark", "pu1k", "--data", dir.file("pu1k"), "--method",
                            "midpoint", "-o", dir.file("out")});
    EXPECT_TRUE(
        test::one_line_error(r, {"several ground truths", "gt_1024", "gt_2048", "--ratio"}));
    r = test::run_cli({"eval", "--benchmark", "pu1k", "--data", dir.file("pu1k"), "--ratio", "4",
                       "--method", "midpoint", "--save-predictions", "-o", dir.file("mid")});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto rows = test::read_csv(dir.file("mid/cases.csv"));
    ASSERT_EQ(rows.size(), 3u);
    for (size_t i = 1; i < rows.size(); ++i) EXPECT_EQ(rows[i][2], "1024") << rows[i][0];
    EXPECT_EQ(read_point_cloud(dir.file("mid/pred/cube.xyz")).size(), 1024);

    save_checkpoint(dir.file("tiny.pt"), *make_backbone(test::tiny_pugcn_config(4, 1)));
    r = test::run_cli({"--threads", "1", "eval", "--benchmark", "pu1k", "--data", dir.file("pu1k"),
                       "--ratio", "4", "--model", dir.file("tiny.pt"), "-o", dir.file("net")});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    rows = test::read_csv(dir.file("net/cases.csv"));
    ASSERT_EQ(rows.size(), 3u);
    for (size_t i = 1; i < rows.size(); ++i) {
        EXPECT_EQ(rows[i][2], "1024") << rows[i][0];
        EXPECT_TRUE(std::isfinite(std::stod(rows[i][4]))) << rows[i][0];
    }
}

TEST(CliBenchmark, BadBenchmarkFoldersAndOptionsAreOneLineErrors) {
    test::TempDir dir;
    make_test_folder(dir.path() / "test");
    const std::string data = dir.file("test");
    auto eval = [&](std::vector<std::string> extra) {
        std::vector<std::string> args = {"eval", "--method", "midpoint", "-o", dir.file("out")};
        args.insert(args.end(), extra.begin(), extra.end());
        return test::run_cli(args);
    };
    EXPECT_TRUE(test::one_line_error(eval({"--benchmark", "pugan"}), {"--data"}));
    EXPECT_TRUE(test::one_line_error(eval({"--benchmark", "pugan", "--data", dir.file("none")}),
                                     {dir.file("none"), "not found"}));
    EXPECT_TRUE(test::one_line_error(eval({"--benchmark", "pugan", "--data", dir.path().string()}),
                                     {"no input_<N> folder"}));
    EXPECT_TRUE(test::one_line_error(eval({"--benchmark", "pugan", "--data", data, "--ratio", "8"}),
                                     {"no gt_2048 folder for ratio 8", "gt_1024"}));
    EXPECT_TRUE(
        test::one_line_error(eval({"--benchmark", "pugan", "--data", data, "--cases", data}),
                             {"either --cases or --benchmark"}));
    EXPECT_TRUE(test::one_line_error(test::run_cli({"eval", "--benchmark", "pugan", "--data", data,
                                                    "--method", "floor", "-o", dir.file("out")}),
                                     {"method 'floor'"}));
    fs::remove(dir.path() / "test" / "gt_1024" / "sphere.xyz");
    EXPECT_TRUE(test::one_line_error(eval({"--benchmark", "pugan", "--data", data}),
                                     {"gt_1024", "no ground truth sphere.xyz"}));
    test::write_file(dir.file("test/gt_1024/sphere.xyz"), "1 2 nan\n");
    EXPECT_TRUE(
        test::one_line_error(eval({"--benchmark", "pugan", "--data", data}), {"sphere.xyz"}));
}

/// An HDF5 patch file of 8 patches on a curved sheet: "poisson_64" (GT, with normals) and
/// "poisson_16" (inputs), the tiny PU-GCN's patch size at 4×.
std::string write_training_patches(const test::TempDir& dir) {
    const at::Tensor gt = test::sheet(8, 64, 5);
    const at::Tensor normals = at::zeros({8, 64, 3}, at::kFloat);
    const std::string path = dir.file("train.h5");
    test::write_hdf5(path, {{"poisson_16", gt.slice(1, 0, 16).contiguous(), {}},
                            {"poisson_64", at::cat({gt, normals}, 2), {}}});
    return path;
}

TEST(CliBenchmark, TrainAndMetaTrainReadAnHdf5PatchFile) {
    test::TempDir dir;
    const std::string h5 = write_training_patches(dir);
    TrainConfig config;
    config.backbone = test::tiny_pugcn_config(4, 11);
    config.train_data = "replaced-by-set.tensors";
    config.run_dir = dir.file("run");
    config.batch_size = 4;
    config.log_every = 1;
    test::write_file(dir.file("train.json"), config.to_json().dump());
    const std::vector<std::string> data = {
        "--set", "train_data=" + h5,          "--set", "val_data=" + h5,
        "--set", "data_input_key=poisson_16", "--set", "data_gt_key=poisson_64"};
    std::vector<std::string> args = {
        "--threads", "1", "train", "--config", dir.file("train.json"), "--set", "steps=2"};
    args.insert(args.end(), data.begin(), data.end());
    auto r = test::run_cli(args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(r.out)["steps"], 2);
    EXPECT_EQ(test::log_records(dir.file("run/log.jsonl"), "loss").size(), 2u);

    save_checkpoint(dir.file("init.pt"), *make_backbone(test::tiny_pugcn_config(4, 11)));
    const nlohmann::json meta = {{"init", dir.file("init.pt")},
                                 {"train_data", "replaced-by-set.tensors"},
                                 {"run_dir", dir.file("meta")},
                                 {"meta", {{"inner_steps", 1}, {"inner_lr", 0.01}}},
                                 {"tasks_per_batch", 4},
                                 {"val_tasks", 4},
                                 {"log_every", 1}};
    test::write_file(dir.file("meta.json"), meta.dump());
    args = {"--threads", "1", "meta-train", "--config", dir.file("meta.json"), "--set", "steps=1"};
    args.insert(args.end(), data.begin(), data.end());
    r = test::run_cli(args);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir.file("meta/state.ckpt")));
}

TEST(CliBenchmark, BadHdf5TrainingFilesAreOneLineErrors) {
    test::TempDir dir;
    const std::string h5 = write_training_patches(dir);
    TrainConfig config;
    config.backbone = test::tiny_pugcn_config(4, 11);
    config.train_data = h5;
    config.run_dir = dir.file("run");
    config.batch_size = 4;
    config.steps = 2;
    test::write_file(dir.file("train.json"), config.to_json().dump());
    auto train = [&](const std::string& file, const std::string& input_key) {
        return test::run_cli({"train", "--config", dir.file("train.json"), "--set",
                              "train_data=" + file, "--set", "data_input_key=" + input_key, "--set",
                              "data_gt_key=poisson_64"});
    };
    // The default input key is not in the file: the message lists what is.
    auto r = test::run_cli({"train", "--config", dir.file("train.json")});
    EXPECT_TRUE(
        test::one_line_error(r, {h5, "no dataset 'poisson_256'", "poisson_16, poisson_64"}));
    const std::string flat = dir.file("flat.h5");
    test::write_hdf5(flat, {{"poisson_16", test::sheet(8, 16, 1)[0], {}},
                            {"poisson_64", test::sheet(8, 64, 1), {}}});
    EXPECT_TRUE(test::one_line_error(train(flat, "poisson_16"), {flat, "has shape [16, 3]"}));
    const std::string bytes = test::read_file(h5);
    const std::string cut = dir.file("cut.h5");
    test::write_file(cut, bytes.substr(0, bytes.size() / 2));
    EXPECT_TRUE(test::one_line_error(train(cut, "poisson_16"), {cut}));
    // A GT of 4× the input for a model of ratio 8.
    config.backbone = test::tiny_pugcn_config(8, 11);
    test::write_file(dir.file("train.json"), config.to_json().dump());
    EXPECT_TRUE(test::one_line_error(train(h5, "poisson_16"), {h5, "ratio 8"}));
}

}  // namespace
}  // namespace pumeta
