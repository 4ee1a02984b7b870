#include "pumeta/eval/grid_floor.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/metrics/metrics.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

std::unique_ptr<Backbone> gridded(double resolution) {
    nlohmann::json config = small_backbone_config("pudense");
    config["resolution"] = resolution;
    return make_backbone(config);
}

TEST(GridFloor, TheGroundTruthOnTheOutputGridApproachesItAsTheGridRefines) {
    // A shifted, scaled sphere: the grid lives in each patch's frame, not the input's.
    at::Tensor input = test::sphere_points(300, 1) * 2.0 + 0.5;
    at::Tensor gt = test::sphere_points(2400, 2) * 2.0 + 0.5;
    const int64_t r = gridded(8)->ratio();
    double previous = 1e9;
    for (double resolution : {4.0, 8.0, 32.0}) {
        at::Tensor out = grid_floor_output(*gridded(resolution), input, gt, r);
        ASSERT_EQ(out.sizes(), (std::vector<int64_t>{300 * r, 3}));
        const double cd = chamfer_distance(out, gt);
        EXPECT_LT(cd, previous) << "resolution " << resolution;
        previous = cd;
    }
    // A fine grid leaves little: far below the input's own CD.
    EXPECT_LT(previous, 0.5 * chamfer_distance(input, gt));
    EXPECT_TRUE(test::throws_input_error(
        [&] { grid_floor_output(*test::small_pugcn(4), input, gt, 4); }, {"continuous"}));
}

}  // namespace
}  // namespace pumeta
