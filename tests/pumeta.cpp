// The public header: the facade gives what the layers below it give, and checks its inputs.
#include "pumeta/pumeta.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "pumeta/inference/model_file.h"
#include "pumeta/inference/upsample.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

TEST(PublicApi, UpsampleIsThePipelineWithTheModelsDefaults) {
    test::TempDir dir;
    const std::string path = dir.file("tiny.pt");
    test::save_tiny_model(path, 1);
    const Model model(path);
    EXPECT_EQ(model.path(), path);
    EXPECT_EQ(model.ratio(), 4);
    EXPECT_EQ(model.backbone(), "pugcn");
    EXPECT_FALSE(model.meta_trained());

    const at::Tensor points = test::sphere_points(200, 3);
    const at::Tensor dense = upsample(model, points);
    ASSERT_EQ(dense.sizes(), (at::IntArrayRef{800, 3}));
    UpsampleOptions options;
    options.ratio = 4;
    const ServedModel served = serve(path, 0);
    EXPECT_TRUE(at::equal(dense, upsample_cloud(*served.model.backbone, points, options).points));

    // Plain values give the same points; 16 = the 4x model twice.
    const Points values = upsample(model, to_points(points));
    EXPECT_TRUE(at::equal(to_tensor(values), dense));
    UpsampleSettings settings;
    settings.ratio = 16;
    EXPECT_EQ(upsample(model, points, settings).size(0), 3200);
}

TEST(PublicApi, AdaptationFollowsTheSettingsAndTheSeed) {
    test::TempDir dir;
    const std::string path = dir.file("tiny.pt");
    test::save_tiny_model(path, 2);
    const Model model(path);
    const at::Tensor points = test::sphere_points(150, 4);
    UpsampleSettings settings;
    settings.tta_steps = 2;
    settings.tta_lr = 0.05;
    settings.seed = 7;
    const at::Tensor adapted = upsample(model, points, settings);
    EXPECT_TRUE(at::equal(adapted, upsample(model, points, settings)));
    EXPECT_FALSE(at::equal(adapted, upsample(model, points)));
}

TEST(PublicApi, BadInputIsAnInputErrorNamingIt) {
    test::TempDir dir;
    const std::string path = dir.file("tiny.pt");
    test::save_tiny_model(path, 1);
    const Model model(path);
    at::Tensor points = test::sphere_points(50, 1);
    points[7][2] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_TRUE(test::throws_input_error([&] { upsample(model, points); },
                                         {"upsample input", "1 of 50", "row 7"}));
    EXPECT_TRUE(test::throws_input_error([&] { metrics(points, points); }, {"prediction"}));
    EXPECT_TRUE(test::throws_input_error([&] { write_points(dir.file("nan.ply"), points); },
                                         {"nan.ply", "NaN"}));
    EXPECT_FALSE(std::filesystem::exists(dir.file("nan.ply")));

    const at::Tensor fine = test::sphere_points(50, 1);
    UpsampleSettings settings;
    settings.ratio = 3;
    EXPECT_TRUE(
        test::throws_input_error([&] { upsample(model, fine, settings); }, {"ratio 3", "ratio 4"}));
    settings.ratio = kMaxUpsampleRatio + 1;
    EXPECT_TRUE(test::throws_input_error([&] { upsample(model, fine, settings); }, {"ratio"}));
    settings = {};
    settings.tta_lr = -1;
    EXPECT_TRUE(test::throws_input_error([&] { upsample(model, fine, settings); }, {"tta_lr"}));
    EXPECT_TRUE(test::throws_input_error([&] { Model(path, -4); }, {"ratio"}));
    EXPECT_TRUE(test::throws_input_error([&] { Model(dir.file("missing.pt")); },
                                         {"missing.pt", "not found"}));
    EXPECT_TRUE(test::throws_input_error([&] { to_points(at::zeros({4, 2})); }, {"[4, 2]"}));
}

TEST(PublicApi, FilesAndMetricsRoundTrip) {
    test::TempDir dir;
    const at::Tensor points = test::sphere_points(64, 5);
    write_points(dir.file("cloud.ply"), points);
    const at::Tensor back = read_points(dir.file("cloud.ply"));
    EXPECT_TRUE(at::equal(back, points));
    const MetricReport same = metrics(back, points);
    EXPECT_EQ(same.cd, 0);
    EXPECT_EQ(same.hd, 0);
    EXPECT_FALSE(same.p2f.has_value());
    // A mesh file gives P2F: points 0.1 above the square [-1,1]² at z = 0, whose corners and
    // centre are the GT (radius √2 from their bounding-box centre).
    test::write_file(dir.file("square.off"),
                     "OFF\n4 2 0\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2\n3 0 2 3\n");
    const at::Tensor gt =
        at::tensor({-1.f, -1.f, 0.f, 1.f, -1.f, 0.f, 1.f, 1.f, 0.f, -1.f, 1.f, 0.f, 0.f, 0.f, 0.f})
            .reshape({5, 3});
    const at::Tensor pred = at::tensor({0.5f, 0.5f, 0.1f, -0.2f, 0.3f, 0.1f}).reshape({2, 3});
    const MetricReport report = metrics(pred, gt, dir.file("square.off"));
    ASSERT_TRUE(report.p2f.has_value());
    EXPECT_NEAR(*report.p2f, 0.1 / std::sqrt(2.0), 1e-6);
    EXPECT_EQ(report.cd, evaluate(pred, gt).cd);
}

}  // namespace
}  // namespace pumeta
