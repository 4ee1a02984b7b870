// Which model file serves a backbone at a ratio in a reproduction: per-ratio files, powers,
// any-ratio main models and files named without a ratio.
#include "pumeta/eval/reproduce_models.h"

#include <gtest/gtest.h>

#include "pumeta/models/backbone.h"
#include "pumeta/models/checkpoint.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

void write_model(const test::TempDir& dir, const std::string& name, nlohmann::json config) {
    save_checkpoint(dir.file(name), *make_backbone(config));
}

TEST(ModelFiles, PerRatioFilesThenPowersOfASmallerRatio) {
    test::TempDir dir;
    nlohmann::json x4 = small_backbone_config("pugcn");
    x4["ratio"] = 4;
    write_model(dir, "pugcn-x4.pt", x4);
    write_model(dir, "pugcn-x4-meta.pt", x4);
    ModelFiles files(dir.path().string(), 8);
    EXPECT_EQ(files.find("pugcn", 4, false), dir.file("pugcn-x4.pt"));
    EXPECT_EQ(files.find("pugcn", 16, false), dir.file("pugcn-x4.pt"));  // 4× twice
    EXPECT_EQ(files.find("pugcn", 4, true), dir.file("pugcn-x4-meta.pt"));
    EXPECT_FALSE(files.find("pugcn", 8, false));
    EXPECT_FALSE(files.find("dispu", 4, false));
}

TEST(ModelFiles, AFileWithoutARatioServesTheRatiosItsWeightsServe) {
    test::TempDir dir;
    write_model(dir, "metapu.pt", small_backbone_config("metapu"));  // any ratio 2..16
    ModelFiles files(dir.path().string(), 8);
    for (int64_t r : {2, 3, 4, 8, 16})
        EXPECT_EQ(files.find("metapu", r, false), dir.file("metapu.pt")) << r;
    EXPECT_FALSE(files.find("metapu", 32, false));
    EXPECT_FALSE(files.find("metapu", 4, true));  // no metapu-meta.pt
    write_model(dir, "metapu-meta.pt", small_backbone_config("metapu"));
    EXPECT_EQ(files.find("metapu", 4, true), dir.file("metapu-meta.pt"));
}

}  // namespace
}  // namespace pumeta
