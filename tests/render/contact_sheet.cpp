#include "pumeta/render/contact_sheet.h"

#include <gtest/gtest.h>

#include "support/test_util.h"

namespace pumeta {
namespace {

TEST(ContactSheet, ShowsTrainingPatchesAndTestCasesReproducibly) {
    test::TempDir dir;
    nlohmann::json config = test::make_tiny_reproduction(dir.path());
    const std::string dataset = config["dataset_dir"];
    ContactSheet a = make_contact_sheet(dataset, 4, 7);
    // 4x4 patches of 256 pixels (plus labels); test cases in rows of 4.
    EXPECT_GE(a.train_patches.width, 4 * 256);
    EXPECT_GE(a.train_patches.height, 4 * 256);
    EXPECT_GE(a.test_cases.width, 4 * 256);
    EXPECT_EQ(a.train_patches.rgb, make_contact_sheet(dataset, 4, 7).train_patches.rgb);
    EXPECT_NE(a.train_patches.rgb, make_contact_sheet(dataset, 4, 8).train_patches.rgb);
    EXPECT_TRUE(test::throws_input_error([&] { make_contact_sheet(dataset, 8, 7); }, {"x8"}));
}

}  // namespace
}  // namespace pumeta
