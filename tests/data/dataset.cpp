// The dataset builder on a miniature raw-data tree made inside the test: splits, human
// exclusion, counts, normalisation, determinism and round trips.
#include "pumeta/data/dataset.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/data/patch_set.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/io.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/triangle_bvh.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

DatasetConfig tiny_config(const std::string& raw) {
    DatasetConfig config;
    config.raw_dir = raw;
    config.ratios = {4};
    config.input_points = 128;
    config.patch_points = 32;
    config.patches_per_mesh = 5;
    config.generated_shapes = 2;
    config.test_fraction = 0.3;
    config.val_fraction = 0.0;
    config.relative_noise = {1.0};
    config.absolute_noise = {0.01};
    return config;
}

class DatasetTest : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        dir_ = new test::TempDir();
        test::make_raw_tree(dir_->path() / "raw");
        manifest_ =
            new nlohmann::json(make_dataset(tiny_config(dir_->file("raw")), dir_->file("out")));
    }
    static void TearDownTestSuite() {
        delete manifest_;
        delete dir_;
    }
    static test::TempDir* dir_;
    static nlohmann::json* manifest_;
};
test::TempDir* DatasetTest::dir_ = nullptr;
nlohmann::json* DatasetTest::manifest_ = nullptr;

TEST_F(DatasetTest, NoModelInTwoSplitsAndHumansOnlyInEvaluation) {
    const nlohmann::json& splits = (*manifest_)["splits"];
    std::set<std::string> seen;
    for (auto& [split, models] : splits.items()) {
        for (const auto& m : models) {
            EXPECT_TRUE(seen.insert(m["id"].get<std::string>()).second)
                << m["id"] << " appears in two splits";
            if (m["human"].get<bool>()) EXPECT_EQ(split, "test-humans") << m["id"];
        }
    }
    ASSERT_TRUE(splits.contains("test-humans"));
    EXPECT_EQ(splits["test-humans"][0]["id"], "furniture/Mini/walker");
    EXPECT_EQ(seen.size(), 4u + 3u + 2u);  // furniture + CGAL + generated
    for (const auto& m : splits["train"]) EXPECT_FALSE(m["human"].get<bool>());
    for (const auto& m : splits["test-scans"]) EXPECT_EQ(m["id"], "cgal/bunny00");
    for (const auto& m : splits["test-aerial"]) EXPECT_EQ(m["id"], "cgal/b9_training");
}

TEST_F(DatasetTest, SplitIntegrityCheckAcceptsTheBuildAndRejectsEachViolation) {
    EXPECT_NO_THROW(check_split_integrity(*manifest_));
    auto error_of = [](const nlohmann::json& manifest) -> std::string {
        try {
            check_split_integrity(manifest);
        } catch (const InternalError& e) {
            return e.what();
        }
        return "no error";
    };
    const nlohmann::json human = (*manifest_)["splits"]["test-humans"][0];
    const nlohmann::json trained = (*manifest_)["splits"]["train"][0];
    nlohmann::json bad = *manifest_;
    bad["splits"]["val"].push_back(human);  // a human figure outside test-humans
    EXPECT_NE(error_of(bad).find("human figure furniture/Mini/walker in split val"),
              std::string::npos)
        << error_of(bad);
    bad = *manifest_;
    bad["splits"]["test-indist"].push_back(trained);  // the same model in two splits
    EXPECT_NE(error_of(bad).find("is in both"), std::string::npos) << error_of(bad);
    nlohmann::json copy;
    for (const auto& m : (*manifest_)["splits"]["train"])
        if (m.contains("sha256")) copy = m;
    ASSERT_FALSE(copy.is_null());
    copy["id"] = "furniture/renamed/copy";  // the same file under another name
    bad = *manifest_;
    bad["splits"]["test-indist"].push_back(copy);
    EXPECT_NE(error_of(bad).find("are the same file"), std::string::npos) << error_of(bad);
    EXPECT_NE(error_of(bad).find("furniture/renamed/copy (test-indist)"), std::string::npos);
}

TEST_F(DatasetTest, EveryRealModelRecordsItsSha256) {
    for (auto& [split, models] : (*manifest_)["splits"].items())
        for (const auto& m : models)
            if (m["source"] != "generator") EXPECT_EQ(m["sha256"].get<std::string>().size(), 64u);
}

TEST_F(DatasetTest, PatchCountsAndPointCounts) {
    PatchSet train = load_patch_set(dir_->file("out/train-x4.tensors"));
    int64_t meshes = static_cast<int64_t>((*manifest_)["splits"]["train"].size());
    EXPECT_EQ(train.num_meshes(), meshes);
    EXPECT_EQ(train.num_patches(), 5 * meshes);
    EXPECT_EQ(train.points.size(0), 128 * 4 * meshes);
    EXPECT_EQ(train.gt_patch(0).size(0), 32 * 4);
    // Clouds are sampled on unit-sphere normalised meshes.
    EXPECT_LE(train.points.norm(2, 1).max().item<float>(), 1.0f + 1e-5f);
}

TEST_F(DatasetTest, TestCasesHaveTheProtocolsCountsAndANormalisedMesh) {
    fs::path cases = dir_->path() / "out" / "cases" / "test-scans" / "x4";
    nlohmann::json index = nlohmann::json::parse(std::ifstream(cases / "cases.json"));
    ASSERT_EQ(index["cases"].size(), 1u);
    fs::path dir = cases / index["cases"][0]["name"].get<std::string>();
    EXPECT_EQ(read_point_cloud((dir / "input.ply").string()).size(), 128);
    EXPECT_EQ(read_point_cloud((dir / "gt.ply").string()).size(), 512);
    EXPECT_EQ(read_point_cloud((dir / "gt_alt.ply").string()).size(), 512);
    EXPECT_EQ(read_point_cloud((dir / "input_rel1.ply").string()).size(), 128);
    EXPECT_EQ(read_point_cloud((dir / "input_abs0.01.ply").string()).size(), 128);
    TriangleMesh mesh = read_mesh((dir / index["cases"][0]["mesh"].get<std::string>()).string());
    at::Tensor used = mesh.vertices.index_select(0, std::get<0>(at::_unique(mesh.faces.flatten())));
    EXPECT_NEAR(used.norm(2, 1).max().item<float>(), 1.0f, 1e-5f);

    fs::path aerial = dir_->path() / "out" / "cases" / "test-aerial" / "x4";
    nlohmann::json aerial_index = nlohmann::json::parse(std::ifstream(aerial / "cases.json"));
    fs::path scan = aerial / aerial_index["cases"][0]["name"].get<std::string>();
    EXPECT_EQ(read_point_cloud((scan / "input.ply").string()).size(), 500);
    EXPECT_EQ(read_point_cloud((scan / "gt.ply").string()).size(), 2000);
}

TEST_F(DatasetTest, ValidationObjectsGetCasesTooAndTrainingObjectsDoNot) {
    test::TempDir out;
    DatasetConfig config = tiny_config(dir_->file("raw"));
    config.val_fraction = 0.6;  // some furniture goes to val
    config.splits = {"train", "val"};
    nlohmann::json manifest = make_dataset(config, out.file("ds"));
    const size_t val_meshes = manifest["splits"]["val"].size();
    ASSERT_GE(val_meshes, 1u);
    nlohmann::json index = nlohmann::json::parse(
        std::ifstream(out.path() / "ds" / "cases" / "val" / "x4" / "cases.json"));
    EXPECT_EQ(index["cases"].size(), val_meshes);
    EXPECT_EQ(manifest["counts"]["val"]["x4"]["cases"], val_meshes);
    fs::path first =
        out.path() / "ds" / "cases" / "val" / "x4" / index["cases"][0]["name"].get<std::string>();
    EXPECT_EQ(read_point_cloud((first / "input.ply").string()).size(), 128);
    EXPECT_EQ(read_point_cloud((first / "gt.ply").string()).size(), 512);
    EXPECT_FALSE(fs::exists(out.path() / "ds" / "cases" / "train"));
    EXPECT_TRUE(fs::exists(out.path() / "ds" / "val-x4.tensors"));
}

TEST_F(DatasetTest, GtSubsetInputsAreARandomPartOfEachRatiosGroundTruth) {
    test::TempDir out;
    DatasetConfig config = tiny_config(dir_->file("raw"));
    config.ratios = {4, 8};
    config.case_inputs = "gt_subset";
    config.splits = {"test-scans"};
    nlohmann::json manifest = make_dataset(config, out.file("ds"));
    EXPECT_EQ(manifest["config"]["case_inputs"], "gt_subset");
    EXPECT_FALSE(tiny_config("raw").to_json().contains("case_inputs"));  // the default
    for (int64_t r : {4, 8}) {
        fs::path dir =
            out.path() / "ds" / "cases" / "test-scans" / ("x" + std::to_string(r)) / "cgal_bunny00";
        at::Tensor input = read_point_cloud((dir / "input.ply").string()).points;
        at::Tensor gt = read_point_cloud((dir / "gt.ply").string()).points;
        ASSERT_EQ(gt.size(0), 128 * r);
        ASSERT_EQ(input.size(0), 128);
        // Every input point is a ground-truth point; no two are the same one.
        KnnResult nearest = knn(gt, input, 1);
        EXPECT_EQ(nearest.sq_distances.max().item<float>(), 0.f);
        EXPECT_EQ(std::get<0>(at::_unique(nearest.indices.flatten())).size(0), 128);
        EXPECT_EQ(read_point_cloud((dir / "input_rel1.ply").string()).size(), 128);
    }
    EXPECT_THROW(DatasetConfig::from_json({{"case_inputs", "random"}}), InputError);
}

TEST_F(DatasetTest, SameSeedSameDatasetAndPatchSetRoundTrips) {
    test::TempDir again;
    make_dataset(tiny_config(dir_->file("raw")), again.file("out"));
    PatchSet a = load_patch_set(dir_->file("out/train-x4.tensors"));
    PatchSet b = load_patch_set(again.file("out/train-x4.tensors"));
    EXPECT_TRUE(a.points.equal(b.points));
    EXPECT_TRUE(a.seeds.equal(b.seeds));
    EXPECT_EQ(a.ids, b.ids);

    save_patch_set(again.file("copy.tensors"), a);
    PatchSet c = load_patch_set(again.file("copy.tensors"));
    EXPECT_TRUE(c.points.equal(a.points));
    EXPECT_TRUE(c.offsets.equal(a.offsets));
    EXPECT_EQ(c.ratio, 4);
    EXPECT_EQ(c.patch_points, 32);
    EXPECT_EQ(load_patch_set_for_ratio(again.file("copy.tensors"), 4).num_patches(),
              a.num_patches());
    EXPECT_TRUE(test::throws_input_error(
        [&] { load_patch_set_for_ratio(again.file("copy.tensors"), 8); },
        {"copy.tensors", "patch set has ratio 4 but the model has ratio 8"}));
}

TEST(PatchLoader, BatchesAreNormalisedDeterministicAndResumable) {
    PatchSet set;
    set.ratio = 4;
    set.patch_points = 16;
    at::Tensor cloud = uniform_random_points(400, 1);
    set.points = cloud / cloud.norm(2, 1, true);
    set.offsets = at::tensor({int64_t{0}, int64_t{400}});
    set.seeds = at::stack({at::zeros({10}, at::kLong), at::arange(10, at::kLong) * 40}, 1);
    set.ids = {"sphere"};
    LoaderOptions options;
    options.batch_size = 4;
    options.augment = false;
    options.seed = 5;
    PatchLoader loader(set, options);
    Batch first = loader.next();
    EXPECT_EQ(first.input.sizes(), (std::vector<int64_t>{4, 16, 3}));
    EXPECT_EQ(first.gt.sizes(), (std::vector<int64_t>{4, 64, 3}));
    // GT patches normalised: centroid 0, radius 1.
    EXPECT_LT(first.gt.mean(1).abs().max().item<float>(), 1e-5f);
    EXPECT_NEAR(first.gt.norm(2, 2).amax(1).min().item<float>(), 1.0f, 1e-5f);
    Batch second = loader.next();

    PatchLoader resumed(set, options);
    resumed.seek(1);
    EXPECT_TRUE(resumed.next().input.equal(second.input));
    PatchLoader again(set, options);
    EXPECT_TRUE(again.next().gt.equal(first.gt));
}

TEST_F(DatasetTest, PartialBuildOfSomeSplitsWritesTheSameFilesAsTheFullBuild) {
    DatasetConfig config = tiny_config(dir_->file("raw"));
    config.splits = {"test-scans"};
    fs::path out = dir_->path() / "partial";
    make_dataset(config, out.string());
    EXPECT_FALSE(fs::exists(out / "train-x4.tensors"));
    EXPECT_FALSE(fs::exists(out / "cases" / "test-indist"));
    EXPECT_FALSE(fs::exists(out / "manifest.json"));
    EXPECT_TRUE(fs::exists(out / "manifest-test-scans-x4.json"));
    fs::path partial_index = out / "cases" / "test-scans" / "x4" / "cases.json";
    fs::path full_index = dir_->path() / "out" / "cases" / "test-scans" / "x4" / "cases.json";
    ASSERT_TRUE(fs::exists(partial_index));
    EXPECT_EQ(test::read_file(partial_index.string()), test::read_file(full_index.string()));
    for (const char* file : {"input.ply", "gt.ply", "gt_alt.ply", "input_rel1.ply"})
        EXPECT_EQ(test::read_file((out / "cases/test-scans/x4/cgal_bunny00" / file).string()),
                  test::read_file(
                      (dir_->path() / "out/cases/test-scans/x4/cgal_bunny00" / file).string()))
            << file;
}

DatasetConfig with_scans(DatasetConfig config) {
    config.scan_scenes = 1;
    config.scan_objects = 4;
    config.scan_splits = {{"test-lidar16", "lidar16", "test"}, {"val-lidar", "lidar16", "train"}};
    return config;
}

// The tiny dataset again, now with a simulated test split and a validation split.
TEST_F(DatasetTest, SimulatedScanSplitsFollowTheRealScanProtocolWithTheirSceneMesh) {
    fs::path out = dir_->path() / "scans";
    nlohmann::json manifest = make_dataset(with_scans(tiny_config(dir_->file("raw"))), out);
    ASSERT_TRUE(manifest.contains("scans"));
    EXPECT_EQ(manifest["counts"]["test-lidar16"]["x4"]["cases"], 1);
    EXPECT_EQ(manifest["counts"]["val-lidar"]["x4"]["cases"], 1);
    EXPECT_EQ(manifest["config"]["scan_splits"].size(), 2u);

    fs::path cases = out / "cases" / "test-lidar16" / "x4";
    nlohmann::json index = nlohmann::json::parse(std::ifstream(cases / "cases.json"));
    ASSERT_EQ(index["cases"].size(), 1u);
    const nlohmann::json& entry = index["cases"][0];
    EXPECT_EQ(entry["gt_alt"], nullptr);
    fs::path dir = cases / entry["name"].get<std::string>();
    at::Tensor input = read_point_cloud((dir / "input.ply").string()).points;
    at::Tensor gt = read_point_cloud((dir / "gt.ply").string()).points;
    EXPECT_EQ(gt.size(0), 4 * input.size(0));
    EXPECT_EQ(gt.size(0), entry["n_gt"].get<int64_t>());
    const nlohmann::json& scene = manifest["scans"]["test-lidar16"]["scenes"][0];
    // GT = the whole sweep but the < r points a 1/r subset leaves over.
    EXPECT_LT(scene["points"].get<int64_t>() - gt.size(0), 4);
    EXPECT_EQ(scene["rays"], 16 * 1800);
    // The input is a subset of the GT (distance 0 to it), both in the unit sphere.
    EXPECT_EQ(knn(gt, input, 1).sq_distances.max().item<float>(), 0.0f);
    EXPECT_LE(gt.norm(2, 1).max().item<float>(), 1.0f + 1e-5f);
    // The scene mesh is in the same frame: returns lie on it up to the range noise.
    TriangleMesh mesh = read_mesh((dir / entry["mesh"].get<std::string>()).string());
    const double sigma = 0.025 / entry["metres_per_unit"].get<double>();
    at::Tensor to_mesh = TriangleBvh(mesh).distances(gt);
    EXPECT_LT(to_mesh.median().item<double>(), 1.5 * sigma);
    EXPECT_LT(to_mesh.max().item<double>(), 6 * sigma);

    // Objects: test scenes from the test sets and fresh shapes, the validation scene from
    // the training split only.
    std::set<std::string> train_ids, test_ids;
    for (auto& [split, models] : manifest["splits"].items())
        for (const auto& m : models)
            (split == "train" ? train_ids : test_ids).insert(m["id"].get<std::string>());
    auto objects_of = [&](const std::string& split) {
        std::vector<std::string> names;
        for (const auto& e : manifest["scans"][split]["scenes"][0]["elements"])
            if (e["kind"] == "object") names.push_back(e["name"].get<std::string>());
        return names;
    };
    ASSERT_FALSE(objects_of("val-lidar").empty());
    for (const std::string& name : objects_of("val-lidar")) EXPECT_EQ(train_ids.count(name), 1u);
    for (const std::string& name : objects_of("test-lidar16")) {
        EXPECT_EQ(train_ids.count(name), 0u) << name;
        EXPECT_TRUE(test_ids.count(name) == 1 || name.rfind("generated/", 0) == 0) << name;
    }

    // The other splits are unchanged by the scans, byte for byte.
    for (const char* file : {"cases/test-scans/x4/cgal_bunny00/gt.ply", "train-x4.tensors",
                             "cases/test-aerial/x4/cases.json"})
        EXPECT_EQ(test::read_file((out / file).string()),
                  test::read_file((dir_->path() / "out" / file).string()))
            << file;
    // Without scans, the manifest's config has no scan fields.
    EXPECT_FALSE((*manifest_)["config"].contains("scan_splits"));

    // A build of the scan split alone writes the same files.
    DatasetConfig only = with_scans(tiny_config(dir_->file("raw")));
    only.splits = {"val-lidar"};
    fs::path partial = dir_->path() / "scans-partial";
    nlohmann::json partial_manifest = make_dataset(only, partial);
    EXPECT_FALSE(partial_manifest["scans"].contains("test-lidar16"));
    EXPECT_FALSE(fs::exists(partial / "train-x4.tensors"));
    for (const char* file :
         {"cases/val-lidar/x4/cases.json", "cases/val-lidar/x4/scene00/gt.ply",
          "cases/val-lidar/x4/scene00/input.ply", "cases/val-lidar/meshes/scene00.ply"})
        EXPECT_EQ(test::read_file((partial / file).string()),
                  test::read_file((out / file).string()))
            << file;
}

TEST(DatasetConfig, RejectsBadScanSplits) {
    auto config_with = [](nlohmann::json scan) {
        return DatasetConfig::from_json({{"scan_splits", nlohmann::json::array({scan})}});
    };
    EXPECT_NO_THROW(config_with({{"split", "test-lidar64"}, {"sensor", "lidar64"}}));
    EXPECT_THROW(config_with({{"split", "test-x"}, {"sensor", "lidar8"}}), InputError);
    EXPECT_THROW(config_with({{"split", "test-x"}, {"sensor", "lidar16"}, {"meshes", "val"}}),
                 InputError);
    EXPECT_THROW(config_with({{"split", "train"}, {"sensor", "lidar16"}}), InputError);
    nlohmann::json twice = {{"split", "test-x"}, {"sensor", "lidar16"}};
    EXPECT_THROW(DatasetConfig::from_json({{"scan_splits", {twice, twice}}}), InputError);
}

TEST_F(DatasetTest, InfoDescribesAPatchSet) {
    std::string file = dir_->file("out/train-x4.tensors");
    PatchSet set = load_patch_set(file);
    test::CommandResult r = test::run_cli({"info", file, "--json"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    nlohmann::json info = nlohmann::json::parse(r.out);
    EXPECT_EQ(info["kind"], "patch set");
    EXPECT_EQ(info["meshes"], set.num_meshes());
    EXPECT_EQ(info["patches"], set.num_patches());
    EXPECT_EQ(info["generated_meshes"], 2);  // tiny_config: two generated shapes, all in train
}

}  // namespace
}  // namespace pumeta
