// HDF5 patch files (PU-GAN's and PU1K's training data) read as patch sets: the patches come back
// exactly, the keys are configurable, and every malformed or hostile file is a one-line
// InputError naming the file.
#include "pumeta/data/hdf5_patches.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "pumeta/data/patch_set.h"
#include "support/hdf5_files.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;
using test::Hdf5Dataset;
using test::throws_input_error;

/// Rows of a [k,3] tensor in lexicographic order, so that two orderings of one set compare.
at::Tensor sorted_rows(const at::Tensor& points) {
    at::Tensor p = points.to(at::kDouble).contiguous();
    std::vector<std::array<double, 3>> rows(p.size(0));
    for (int64_t i = 0; i < p.size(0); ++i)
        for (int d = 0; d < 3; ++d) rows[i][d] = p[i][d].item<double>();
    std::sort(rows.begin(), rows.end());
    at::Tensor out = at::empty({p.size(0), 3}, at::kDouble);
    for (int64_t i = 0; i < p.size(0); ++i)
        for (int d = 0; d < 3; ++d) out[i][d] = rows[i][d];
    return out;
}

/// PU-GAN's layout: P patches of n input points and 4n GT points, with normals (6 columns).
struct Patches {
    at::Tensor input, gt;  // float64 [P,n,6], [P,4n,6]
};

Patches make_patches(int64_t patches, int64_t n, uint64_t seed) {
    at::Generator generator = at::detail::createCPUGenerator(seed);
    return {at::randn({patches, n, 6}, generator, at::kDouble),
            at::randn({patches, 4 * n, 6}, generator, at::kDouble)};
}

class Hdf5Patches : public ::testing::Test {
  protected:
    std::string write(const std::string& name, const std::vector<Hdf5Dataset>& datasets) {
        std::string path = dir_.file(name);
        test::write_hdf5(path, datasets);
        return path;
    }
    test::TempDir dir_;
};

TEST_F(Hdf5Patches, GtPatchesComeBackExactlyWithoutTheirNormals) {
    Patches p = make_patches(5, 16, 1);
    std::string path =
        write("train.h5", {{"poisson_256", p.input, {}}, {"poisson_1024", p.gt, {}}});
    PatchSet set = read_hdf5_patches(path);
    EXPECT_EQ(set.ratio, 4);
    EXPECT_EQ(set.patch_points, 16);
    ASSERT_EQ(set.num_patches(), 5);
    EXPECT_EQ(set.num_meshes(), 5);
    for (int64_t s = 0; s < 5; ++s) {
        at::Tensor expected = p.gt[s].slice(1, 0, 3).to(at::kFloat);
        at::Tensor patch = set.gt_patch(s);
        ASSERT_EQ(patch.sizes(), expected.sizes());
        EXPECT_TRUE(at::equal(sorted_rows(patch), sorted_rows(expected))) << "patch " << s;
        // The seed is the point nearest the patch centroid (computed here in double).
        at::Tensor xyz = expected.to(at::kDouble);
        at::Tensor d = (xyz - xyz.mean(0)).pow(2).sum(1);
        EXPECT_EQ(set.seeds[s][1].item<int64_t>(), d.argmin().item<int64_t>());
        EXPECT_TRUE(at::equal(patch[0], expected[set.seeds[s][1].item<int64_t>()]));
    }
}

TEST_F(Hdf5Patches, KeysAreConfigurableAndMayNameGroups) {
    Patches p = make_patches(3, 8, 2);
    std::string path = write("pu1k.hdf5", {{"data/in", p.input.to(at::kFloat), {}},
                                           {"data/gt", p.gt.slice(2, 0, 3).to(at::kFloat), {}}});
    PatchSet set = read_hdf5_patches(path, {"data/in", "data/gt"}, 4);
    EXPECT_EQ(set.num_patches(), 3);
    EXPECT_EQ(set.patch_points, 8);
    // The patch-set loader dispatches on the extension, and a loader draws batches from it.
    PatchSet loaded = load_patch_set_for_ratio(path, 4, {"data/in", "data/gt"});
    EXPECT_TRUE(at::equal(loaded.points, set.points));
    LoaderOptions options;
    options.batch_size = 2;
    PatchLoader loader(loaded, options);
    Batch batch = loader.next();
    EXPECT_EQ(batch.input.sizes(), (std::vector<int64_t>{2, 8, 3}));
    EXPECT_EQ(batch.gt.sizes(), (std::vector<int64_t>{2, 32, 3}));
}

TEST_F(Hdf5Patches, AMissingKeyNamesTheDatasetsPresent) {
    Patches p = make_patches(2, 8, 3);
    std::string path = write("k.h5", {{"poisson_256", p.input, {}}, {"label", p.gt, {}}});
    EXPECT_TRUE(throws_input_error([&] { read_hdf5_patches(path); },
                                   {path, "no dataset 'poisson_1024'", "label", "poisson_256"}));
    EXPECT_TRUE(throws_input_error(
        [&] {
            read_hdf5_patches(path, {"poisson_256", "a/b/c"});
        },
        {path, "no dataset 'a/b/c'"}));
}

TEST_F(Hdf5Patches, WrongShapesCountsAndRatiosAreOneLineErrors) {
    Patches p = make_patches(3, 8, 4);
    auto error_of = [&](const std::string& name, const at::Tensor& input, const at::Tensor& gt,
                        std::vector<std::string> fragments, int64_t ratio = 0) {
        std::string path = write(name, {{"poisson_256", input, {}}, {"poisson_1024", gt, {}}});
        fragments.push_back(path);
        return throws_input_error([&] { read_hdf5_patches(path, {}, ratio); }, fragments);
    };
    EXPECT_TRUE(error_of("rank.h5", p.input[0], p.gt, {"'poisson_256' has shape [8, 6]"}));
    EXPECT_TRUE(error_of("columns.h5", p.input, p.gt.slice(2, 0, 2),
                         {"'poisson_1024' has shape [3, 32, 2]"}));
    EXPECT_TRUE(error_of("count.h5", p.input, p.gt.slice(0, 0, 2),
                         {"'poisson_256' has 3 patches but 'poisson_1024' has 2"}));
    EXPECT_TRUE(error_of("multiple.h5", p.input, p.gt.slice(1, 0, 30),
                         {"30 points per patch", "not a whole multiple"}));
    EXPECT_TRUE(error_of("ratio.h5", p.input, p.gt, {"32 points per patch", "ratio 8"}, 8));
    EXPECT_TRUE(error_of("int.h5", p.input.to(at::kInt), p.gt, {"not hold floating-point"}));
    at::Tensor nan = p.gt.clone();
    nan[2][5][1] = std::nan("");
    EXPECT_TRUE(error_of("nan.h5", p.input, nan, {"'poisson_1024' patch 2", "non-finite"}));
    at::Tensor inf = p.input.clone();
    inf[1][0][0] = INFINITY;
    EXPECT_TRUE(error_of("inf.h5", inf, p.gt, {"'poisson_256' patch 1", "non-finite"}));
    // load_patch_set_for_ratio says the same for the model's ratio.
    std::string path = write("ok.h5", {{"poisson_256", p.input, {}}, {"poisson_1024", p.gt, {}}});
    EXPECT_TRUE(throws_input_error([&] { load_patch_set_for_ratio(path, 16); },
                                   {path, "ratio 16", "data_gt_key"}));
}

TEST_F(Hdf5Patches, MissingNotHdf5TruncatedAndHollowFilesAreOneLineErrors) {
    std::string missing = dir_.file("missing.h5");
    EXPECT_TRUE(throws_input_error([&] { read_hdf5_patches(missing); }, {missing, "not found"}));
    std::string text = dir_.file("text.h5");
    test::write_file(text, "x y z\n1 2 3\n");
    EXPECT_TRUE(throws_input_error([&] { read_hdf5_patches(text); }, {text, "not an HDF5 file"}));
    EXPECT_TRUE(
        throws_input_error([&] { read_hdf5_patches(dir_.path().string() + "/"); }, {"not a file"}));

    Patches p = make_patches(40, 32, 5);
    std::string whole =
        write("whole.h5", {{"poisson_256", p.input, {}}, {"poisson_1024", p.gt, {}}});
    const std::string bytes = test::read_file(whole);
    for (size_t keep : {bytes.size() / 2, bytes.size() - 100, size_t{600}}) {
        std::string cut = dir_.file("cut" + std::to_string(keep) + ".h5");
        test::write_file(cut, bytes.substr(0, keep));
        EXPECT_TRUE(throws_input_error([&] { read_hdf5_patches(cut); }, {cut})) << keep;
    }

    // Datasets that claim a shape but hold nothing, small and beyond the size limit.
    std::string hollow = write(
        "hollow.h5", {{"poisson_256", {}, {4, 8, 3}}, {"poisson_1024", p.gt.slice(0, 0, 4), {}}});
    EXPECT_TRUE(throws_input_error([&] { read_hdf5_patches(hollow); },
                                   {hollow, "'poisson_256' holds no stored data"}));
    std::string huge = write("huge.h5", {{"poisson_256", p.input, {}},
                                         {"poisson_1024", {}, {int64_t{1} << 20, 512, 6}}});
    EXPECT_TRUE(
        throws_input_error([&] { read_hdf5_patches(huge); },
                           {huge, "'poisson_1024' has shape [1048576, 512, 6]", "more than"}));
}

TEST_F(Hdf5Patches, CorruptedBytesGiveAPatchSetOrAnInputErrorNeverACrash) {
    Patches p = make_patches(6, 8, 6);
    std::string whole =
        write("whole.h5", {{"poisson_256", p.input, {}}, {"poisson_1024", p.gt, {}}});
    const std::string bytes = test::read_file(whole);
    std::mt19937_64 rng(7);
    int errors = 0;
    for (int trial = 0; trial < 60; ++trial) {
        std::string damaged = bytes;
        // Flip a few bytes in the first 4 KiB: the superblock, object headers, B-trees.
        for (int k = 0; k < 4; ++k)
            damaged[rng() % std::min<size_t>(4096, damaged.size())] ^=
                static_cast<char>(1 + rng() % 255);
        std::string path = dir_.file("damaged.h5");
        test::write_file(path, damaged);
        try {
            PatchSet set = read_hdf5_patches(path);
            EXPECT_EQ(set.patch_points * set.ratio, set.gt_patch(0).size(0));
        } catch (const InputError& error) {
            ++errors;
            EXPECT_EQ(std::string(error.what()).find('\n'), std::string::npos) << error.what();
            EXPECT_EQ(std::string(error.what()).rfind(path, 0), 0u) << error.what();
        }
    }
    EXPECT_GT(errors, 0);  // the damage is not all in bytes that nothing reads
}

}  // namespace
}  // namespace pumeta
