// The dataset layout: paths compose as data/dataset.h draws them, and the relative mesh
// entry of cases.json resolves to the mesh that make_dataset writes.
#include "pumeta/data/layout.h"

#include <gtest/gtest.h>

#include <set>

namespace pumeta {
namespace {

namespace fs = std::filesystem;

TEST(Layout, PathsFollowTheDatasetLayout) {
    const fs::path dataset = "data/dataset";
    EXPECT_EQ(layout::cases_dir(dataset, "test-scans", 8),
              fs::path("data/dataset/cases/test-scans/x8"));
    EXPECT_EQ(layout::case_index_path(layout::cases_dir(dataset, "val", 4)),
              fs::path("data/dataset/cases/val/x4/cases.json"));
    EXPECT_EQ(layout::patch_set_path(dataset, "train", 16),
              fs::path("data/dataset/train-x16.tensors"));
    EXPECT_EQ(layout::patch_set_file("val", 4), "val-x4.tensors");
    EXPECT_EQ(layout::ratio_tag(4), "x4");
}

TEST(Layout, TheMeshEntryOfACaseResolvesToItsMesh) {
    const fs::path dataset = "/tmp/ds";
    const fs::path case_dir = layout::cases_dir(dataset, "test-indist", 4) / "chair_0001";
    EXPECT_EQ((case_dir / layout::case_mesh_entry("chair_0001")).lexically_normal(),
              layout::case_mesh_path(dataset, "test-indist", "chair_0001"));
}

TEST(Layout, TestSetsAreDistinctAndTheCasesDirOfEachIsItsOwn) {
    std::set<fs::path> dirs;
    for (const char* set : layout::kTestSets) dirs.insert(layout::cases_dir("d", set, 4));
    EXPECT_EQ(dirs.size(), layout::kTestSets.size());
}

}  // namespace
}  // namespace pumeta
