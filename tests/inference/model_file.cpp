// Which shipped model `pumeta upsample` picks when no --model is given.
#include "pumeta/inference/model_file.h"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>

#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

TEST(DefaultModel, ANativeModelForTheRatioElseAPowerOfAShippedOne) {
    test::TempDir dir;
    test::write_file(dir.file("pugcn-x4.pt"), "x");
    setenv("PUMETA_MODELS", dir.path().c_str(), 1);
    auto name = [](int64_t ratio) { return fs::path(default_model_for_ratio(ratio)).filename(); };
    EXPECT_EQ(name(0), "pugcn-x4.pt");
    EXPECT_EQ(name(4), "pugcn-x4.pt");
    EXPECT_EQ(name(16), "pugcn-x4.pt");
    EXPECT_EQ(name(8), "pugcn-x4.pt");  // no 8x model: the 4x one, which then rejects 8
    test::write_file(dir.file("pugcn-x8.pt"), "x");
    EXPECT_EQ(name(8), "pugcn-x8.pt");
    EXPECT_EQ(name(64), "pugcn-x8.pt");
    EXPECT_EQ(name(16), "pugcn-x4.pt");
    unsetenv("PUMETA_MODELS");
}

}  // namespace
}  // namespace pumeta
