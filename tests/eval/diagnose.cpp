#include "pumeta/eval/diagnose.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "support/test_util.h"

namespace pumeta {
namespace {

ValidationSet sheet_patches(int64_t ratio) {
    at::Tensor gt = test::sheet(6, 16 * ratio, 3);
    ValidationSet set;
    set.gt = gt;
    set.input = gt.slice(1, 0, 16 * ratio, ratio).contiguous();
    set.input_cd = mean_chamfer(set.input, set.gt);
    return set;
}

TEST(Diagnose, ReportsTheModelsCdAndAveragesItsBackbonesFields) {
    // A backbone without a decomposition: its CD next to the input's.
    auto pugcn = make_backbone(test::tiny_pugcn_config(4, 1));
    ValidationSet set = sheet_patches(4);
    nlohmann::json plain = diagnose_patches(*pugcn, set, 4);
    EXPECT_EQ(plain["patches"], 6);
    EXPECT_DOUBLE_EQ(plain["cd"].get<double>(), validation_cd(*pugcn, set));
    EXPECT_DOUBLE_EQ(plain["input_cd"].get<double>(), set.input_cd);
    EXPECT_FALSE(plain.contains("floor_cd"));
    // PU-Dense's fields are the means over the patches, whatever the batch.
    auto pudense = make_backbone(small_backbone_config("pudense"));
    ValidationSet dense = sheet_patches(pudense->ratio());
    nlohmann::json by_two = diagnose_patches(*pudense, dense, 2);
    nlohmann::json fields = pudense->diagnose(dense.input, dense.gt);
    double sum = 0;
    for (const auto& v : fields["floor_cd"]) sum += v.get<double>();
    EXPECT_NEAR(by_two["floor_cd"].get<double>(), sum / 6, 1e-12);
    EXPECT_TRUE(test::throws_input_error([&] { diagnose_patches(*pudense, dense, 0); }, {"batch"}));
}

}  // namespace
}  // namespace pumeta
