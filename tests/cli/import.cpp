// `pumeta import` end to end through the binary: foreign, truncated and mismatched files are
// one-line errors with exit 2 and no output file; the released Grad-PU PU-GAN weights (read
// from ../shared, skipped without it) become a model that `info`, `upsample` and `eval` accept,
// and that scores three public PU-GAN test meshes as the original does.
#include <gtest/gtest.h>

#include <filesystem>

#include "pumeta/geometry/io.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

fs::path shared_dir() { return fs::path(test::source_dir()) / ".." / "shared"; }

fs::path gradpu_weights() {
    return shared_dir() / "weights" / "gradpu" / "pugan-ckpt-epoch-60.pth";
}

test::CommandResult import(const std::string& file, const std::string& out,
                           const std::string& format = "gradpu") {
    return test::run_cli({"import", "--from", format, file, "-o", out});
}

TEST(CliImport, AFileThatIsNoTorchArchiveIsAOneLineErrorAndWritesNothing) {
    test::TempDir dir;
    const std::string out = dir.file("out.pt");
    // A pumeta model file is a LibTorch archive, not a torch.save state dict.
    const std::string foreign = test::source_dir() + "/models/pugcn-x4.pt";
    EXPECT_TRUE(test::one_line_error(import(foreign, out), {"pugcn-x4.pt"}));
    const std::string text = dir.file("weights.pth");
    test::write_file(text, "not an archive\n");
    EXPECT_TRUE(test::one_line_error(import(text, out), {"weights.pth"}));
    EXPECT_TRUE(test::one_line_error(import(dir.file("missing.pth"), out), {"missing.pth"}));
    EXPECT_FALSE(fs::exists(out));
    // An unknown format is refused before any file is read.
    const auto r = import(foreign, out, "pugan");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_FALSE(fs::exists(out));
}

TEST(CliImport, TruncatedAndMismatchedReleasedFilesAreOneLineErrors) {
    if (!fs::exists(gradpu_weights())) GTEST_SKIP() << "no " << gradpu_weights().string();
    test::TempDir dir;
    const std::string out = dir.file("out.pt");
    const std::string whole = test::read_file(gradpu_weights().string());
    for (size_t keep : {size_t{100}, whole.size() / 2, whole.size() - 30}) {
        const std::string cut = dir.file("cut-" + std::to_string(keep) + ".pth");
        test::write_file(cut, whole.substr(0, keep));
        EXPECT_TRUE(
            test::one_line_error(import(cut, out), {"cut-" + std::to_string(keep) + ".pth"}))
            << keep << " of " << whole.size() << " bytes";
    }
    // Another network's weights: a Grad-PU tensor it lacks is named.
    const fs::path pugaussian =
        shared_dir() / "weights" / "pugaussian" / "pu_gaussian_pugan_Best.pth";
    if (fs::exists(pugaussian))
        EXPECT_TRUE(test::one_line_error(import(pugaussian.string(), out),
                                         {"pu_gaussian_pugan_Best.pth", "tensor"}));
    EXPECT_FALSE(fs::exists(out));
}

// The imported model through every inference command: info reports the original's parameter
// count and where the weights came from; upsample writes exactly 4N points.
TEST(CliImport, ImportedGradPuWeightsServeInfoAndUpsample) {
    if (!fs::exists(gradpu_weights())) GTEST_SKIP() << "no " << gradpu_weights().string();
    test::TempDir dir;
    const std::string model = dir.file("gradpu.pt");
    const auto imported = import(gradpu_weights().string(), model);
    ASSERT_EQ(imported.exit_code, 0) << imported.err;
    const auto info = test::run_cli({"info", model});
    ASSERT_EQ(info.exit_code, 0) << info.err;
    EXPECT_NE(info.out.find("gradpu"), std::string::npos) << info.out;
    EXPECT_NE(info.out.find("67073"), std::string::npos) << info.out;
    EXPECT_NE(info.out.find("pugan-ckpt-epoch-60.pth"), std::string::npos) << info.out;

    const std::string input = dir.file("sphere.xyz"), output = dir.file("dense.xyz");
    write_point_cloud(input, {test::sphere_points(300, 5), {}, {}});
    const auto up = test::run_cli(
        {"--threads", "1", "upsample", input, "-o", output, "--model", model, "--ratio", "4"});
    ASSERT_EQ(up.exit_code, 0) << up.err;
    const at::Tensor dense = read_point_cloud(output).points;
    EXPECT_EQ(dense.size(0), 1200);
    EXPECT_EQ(count_distinct_points(dense), 1200);
    // On the unit sphere it came from (the refinement moves points by about 1e-3 here).
    const at::Tensor radius = dense.norm(2, 1);
    EXPECT_LT((radius - 1).abs().max().item<double>(), 0.05);
}

// Agreement with the original (Grad-PU's own code and these weights, step size 50, CPU,
// PyTorch 1.13, measured on the public meshes): 4x CD per mesh within 2 %.
TEST(CliImport, ImportedGradPuScoresThreePublicMeshesAsTheOriginal) {
    const fs::path bench = shared_dir() / "benchmarks" / "pugan-test";
    if (!fs::exists(gradpu_weights()) || !fs::is_directory(bench / "input_2048"))
        GTEST_SKIP() << "no " << shared_dir().string();
    test::TempDir dir;
    const std::string model = dir.file("gradpu.pt");
    ASSERT_EQ(import(gradpu_weights().string(), model).exit_code, 0);
    const fs::path data = dir.path() / "pugan";
    const std::map<std::string, double> original = {
        {"camel", 0.2086}, {"fandisk", 0.2436}, {"star", 0.3857}};
    for (const std::string folder : {"input_2048", "gt_8192", "original_meshes"}) {
        fs::create_directories(data / folder);
        for (const auto& [name, cd] : original) {
            const std::string file = name + (folder == "original_meshes" ? ".off" : ".xyz");
            fs::create_symlink(fs::absolute(bench / folder / file), data / folder / file);
        }
    }
    const std::string out = dir.file("eval");
    const auto r = test::run_cli({"--threads", "1", "eval", "--benchmark", "pugan", "--data",
                                  data.string(), "--model", model, "--ratio", "4", "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto rows = test::read_csv(out + "/cases.csv");
    ASSERT_EQ(rows.size(), 4u);
    ASSERT_EQ(rows[0][4], "cd_1e3");
    for (size_t i = 1; i < rows.size(); ++i) {
        const double expected = original.at(rows[i][0]);
        EXPECT_NEAR(std::stod(rows[i][4]), expected, 0.02 * expected) << rows[i][0];
    }
}

}  // namespace
}  // namespace pumeta
