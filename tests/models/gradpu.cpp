#include "pumeta/models/gradpu.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>
#include <torch/csrc/autograd/autograd.h>

#include <filesystem>
#include <set>
#include <tuple>

#include "pumeta/geometry/io.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/models/import.h"
#include "pumeta/nn/parameters.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

namespace fs = std::filesystem;

/// All pairwise distances of a [n,3] and b [m,3] in double precision (at::cdist in float uses
/// a matrix product whose rounding reaches 1e-4 here).
at::Tensor exact_distances(const at::Tensor& a, const at::Tensor& b) {
    return at::cdist(a.to(at::kDouble), b.to(at::kDouble));
}

/// Every midpoint of a point of x [n,3] and one of its `count` nearest (itself included),
/// from all pairs.
at::Tensor midpoint_pool(const at::Tensor& x, int64_t count) {
    at::Tensor order = std::get<1>(exact_distances(x, x).sort(1));
    std::vector<at::Tensor> pool;
    for (int64_t i = 0; i < x.size(0); ++i)
        for (int64_t j = 0; j < count; ++j)
            pool.push_back((x[i] + x[order[i][j].item<int64_t>()]) / 2);
    return at::stack(pool);
}

GradPu small_model(nlohmann::json changes = nlohmann::json::object()) {
    nlohmann::json config = gradpu_small_config();
    config.update(changes);
    return GradPu(GradPuOptions::from_json(config));
}

TEST(GradPu, TheOriginalsSizeHas67073ParametersAndTheStatisticsOfFortyBatchNorms) {
    GradPu model(GradPuOptions{});
    EXPECT_EQ(count_parameters(model.parameters()), 67073);
    EXPECT_EQ(model.buffers().size(), 80u);  // running mean and variance of each
    // Forty batch norms of 32 channels: the initial conv, four per dense layer, a transition
    // per block.
    EXPECT_EQ(count_parameters(model.buffers()), 2 * 40 * 32);
}

// Every output is the midpoint of an input point and one of its 2r nearest (itself included),
// checked against all pairs; the outputs are distinct.
TEST(GradPu, MidpointInterpolationPicksMidpointsOfTheTwoRNearestByFps) {
    const int64_t n = 40, r = 4;
    at::Tensor x = test::sheet(2, n, 5);
    at::Tensor y = midpoint_interpolate(x, r);
    ASSERT_EQ(y.sizes(), (std::vector<int64_t>{2, r * n, 3}));
    for (int64_t b = 0; b < 2; ++b) {
        at::Tensor gap = std::get<0>(exact_distances(y[b], midpoint_pool(x[b], 2 * r)).min(1));
        EXPECT_LT(gap.max().item<double>(), 1e-6) << "batch " << b;
        EXPECT_EQ(count_distinct_points(y[b].contiguous()), r * n);
    }
}

// The regressor's gradient with respect to a query (what the refinement descends) against
// central differences, in double precision.
TEST(GradPu, DistanceGradientWithRespectToTheQueryMatchesFiniteDifferences) {
    GradPu model = small_model();
    for (auto& [name, p] : model.parameters()) p = p.detach().to(at::kDouble).requires_grad_(true);
    for (auto& [name, b] : model.buffers()) b = b.to(at::kDouble);
    at::Tensor p = midpoint_interpolate(test::sheet(1, 16, 6, at::kDouble), 4);
    // Queries off the patch points (where the 3-NN weights are smooth).
    at::Generator gen = at::detail::createCPUGenerator(7);
    at::Tensor q = (p + 0.01 * at::randn(p.sizes(), gen, p.options())).detach();
    at::Tensor qv = q.clone().requires_grad_(true);
    at::Tensor grad =
        torch::autograd::grad({model.distance(p, qv, model.parameters()).sum()}, {qv})[0];
    const double h = 1e-6;
    int64_t checked = 0;
    for (int64_t i = 0; i < q.size(1); i += 7) {
        for (int64_t c = 0; c < 3; ++c) {
            at::Tensor plus = q.clone(), minus = q.clone();
            plus[0][i][c] += h;
            minus[0][i][c] -= h;
            const double numeric =
                (model.distance(p, plus, model.parameters()).sum().item<double>() -
                 model.distance(p, minus, model.parameters()).sum().item<double>()) /
                (2 * h);
            EXPECT_NEAR(grad[0][i][c].item<double>(), numeric, 1e-5 * (1 + std::abs(numeric)))
                << "query " << i << " axis " << c;
            ++checked;
        }
    }
    EXPECT_GT(checked, 20);
}

// A descent step lowers the mean predicted (clamped) distance for a small step, and the
// original's cloud-mean rule is the per-point rule with the step over the point count.
TEST(GradPu, RefinementDescendsThePredictedDistanceAndTheStepRulesAgree) {
    at::NoGradGuard no_grad;
    at::Tensor x = test::sheet(2, 16, 8);
    // Positive regressor weights and biases keep its ReLUs live (at random weights the
    // predicted distance is 0 everywhere here, and nothing moves).
    auto live = [](GradPu& model) {
        for (auto& [name, p] : model.parameters())
            if (name.rfind("regressor.", 0) == 0) p = p.abs() + 0.01;
    };
    auto make = [&](nlohmann::json changes) {
        changes["max_distance"] = 10.0;
        GradPu model = small_model(changes);
        live(model);
        return model;
    };
    GradPu before = make({{"steps", 0}});
    GradPu after = make({{"steps", 1}, {"step_rule", "per_point"}, {"step_size", 0.01}});
    at::Tensor start = before.upsample(x);
    at::Tensor moved = after.upsample(x);
    ASSERT_FALSE(at::equal(start, moved));
    // Both in the frame the refinement runs in (each interpolated patch on its unit sphere).
    auto mean_distance = [&](const at::Tensor& points) {
        at::Tensor interpolated = midpoint_interpolate(x, 4);
        at::Tensor centroid = interpolated.mean(1, true);
        at::Tensor radius = (interpolated - centroid).norm(2, -1, true).amax(1, true);
        return after
            .distance((interpolated - centroid) / radius, (points - centroid) / radius,
                      after.parameters())
            .mean()
            .item<double>();
    };
    EXPECT_LT(mean_distance(moved), mean_distance(start));

    GradPu per_point = make({{"step_rule", "per_point"}, {"step_size", 0.02 / 64}});
    GradPu cloud_mean = make({{"step_rule", "cloud_mean"}, {"step_size", 0.02}});
    ASSERT_FALSE(at::equal(per_point.upsample(x), before.upsample(x)));
    EXPECT_TRUE(at::allclose(per_point.upsample(x), cloud_mean.upsample(x), 1e-5, 1e-6));
}

// The whole-cloud pipeline: exactly the patches' points come back (int(rN / 1024 · 3) patches
// of 1,024 at the original's sizes), and with no steps they are interpolated points.
TEST(GradPu, CloudPipelineReturnsEveryRefinedPointOfItsPatches) {
    at::NoGradGuard no_grad;
    GradPu model = small_model({{"steps", 0}});
    at::Tensor cloud = test::sphere_points(100, 9);
    at::Tensor candidates = model.cloud_candidates(cloud, model.parameters(), 0);
    // 400 interpolated points: int(400 / 64 · 3) = 18 patches of 64.
    EXPECT_EQ(candidates.sizes(), (std::vector<int64_t>{18 * 64, 3}));
    // Midpoints of a point and one of its 8 nearest (itself included).
    at::Tensor gap = std::get<0>(exact_distances(candidates, midpoint_pool(cloud, 8)).min(1));
    EXPECT_LT(gap.max().item<double>(), 1e-5);
}

// The released PU-GAN weights (skipped without ../shared): the imported network, through the
// original's whole-cloud pipeline on a public test mesh input, moves the interpolated points
// towards the mesh's surface (its dense ground truth), as the original does.
TEST(GradPu, ImportedReleasedWeightsMoveInterpolatedPointsTowardsTheSurface) {
    const fs::path root = fs::path(test::source_dir()) / ".." / "shared";
    const fs::path weights = root / "weights" / "gradpu" / "pugan-ckpt-epoch-60.pth";
    const fs::path input = root / "benchmarks" / "pugan-test" / "input_2048" / "camel.xyz";
    const fs::path gt = root / "benchmarks" / "pugan-test" / "gt_32768" / "camel.xyz";
    if (!fs::exists(weights) || !fs::exists(input)) GTEST_SKIP() << "no " << root.string();
    std::unique_ptr<Backbone> model = import_weights("gradpu", weights.string());
    EXPECT_EQ(count_parameters(model->parameters()), 67073);
    at::NoGradGuard no_grad;
    const at::Tensor cloud = read_point_cloud(input.string()).points;
    const at::Tensor dense = read_point_cloud(gt.string()).points.contiguous();
    GradPuOptions plain = dynamic_cast<GradPu&>(*model).options();
    plain.steps = 0;
    GradPu interpolation(plain);
    for (auto& [name, p] : interpolation.parameters()) p = model->parameters().at(name);
    for (auto& [name, b] : interpolation.buffers()) b = model->buffers().at(name);
    auto to_surface = [&](const at::Tensor& points) {
        return knn(dense, points.contiguous(), 1).sq_distances.sqrt().mean().item<double>();
    };
    const double refined = to_surface(model->cloud_candidates(cloud, model->parameters(), 0));
    const double start =
        to_surface(interpolation.cloud_candidates(cloud, interpolation.parameters(), 0));
    EXPECT_LT(refined, start);
}

}  // namespace
}  // namespace pumeta
