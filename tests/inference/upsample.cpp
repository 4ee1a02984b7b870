#include "pumeta/inference/upsample.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <gtest/gtest.h>

#include <cmath>

#include "geometry/mesh_oracles.h"
#include "pumeta/core/error.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/metrics.h"
#include "pumeta/models/backbone.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using test::small_pugcn;
using test::sphere_points;

TEST(UpsampleCloud, OutputCountIsExactlyRatioTimesInputForEveryRatio) {
    at::Tensor input = sphere_points(300, 1);
    for (int64_t r : {4, 8, 16}) {
        auto model = small_pugcn(r == 16 ? 4 : r);
        UpsampleOptions options;
        options.ratio = r;
        UpsampleResult result = upsample_cloud(*model, input, options);
        EXPECT_EQ(result.points.size(0), r * 300) << "ratio " << r;
        EXPECT_EQ(result.points.size(1), 3);
        EXPECT_TRUE(result.points.isfinite().all().item<bool>());
    }
}

TEST(UpsampleCloud, InputsSmallerThanAPatchWork) {
    auto model = small_pugcn(4);
    for (int64_t n : {12, 40}) {
        UpsampleResult result = upsample_cloud(*model, sphere_points(n, 2), {});
        EXPECT_EQ(result.points.size(0), 4 * n);
    }
}

TEST(UpsampleCloud, OwnershipMergeGivesExactCountOnLargeInputs) {
    auto model = small_pugcn(4);
    UpsampleOptions options;
    // The merge used for huge even clouds, asked for: these random points are irregular,
    // which by default takes FPS at any size and keeps the input points.
    options.selection = Selection::kOwnership;
    options.keep_input = false;
    UpsampleResult result = upsample_cloud(*model, sphere_points(2000, 3), options);
    EXPECT_EQ(result.points.size(0), 8000);
    options.keep_input = true;
    EXPECT_EQ(upsample_cloud(*model, sphere_points(2000, 3), options).points.size(0), 8000);
}

TEST(UpsampleCloud, SameSeedSameOutputAndModelUnchangedByAdaptation) {
    auto model = small_pugcn(4);
    ParamMap before;
    for (auto& [name, p] : model->parameters()) before[name] = p.detach().clone();
    UpsampleOptions options;
    options.adaptation.inner.steps = 2;
    options.adaptation.inner.step_size = 0.01;
    at::Tensor input = sphere_points(200, 4);
    UpsampleResult a = upsample_cloud(*model, input, options);
    UpsampleResult b = upsample_cloud(*model, input, options);
    EXPECT_TRUE(a.points.equal(b.points));
    EXPECT_TRUE(std::isfinite(a.loss_before));
    EXPECT_TRUE(std::isfinite(a.loss_after));
    for (auto& [name, p] : model->parameters()) EXPECT_TRUE(p.equal(before[name])) << name;
}

TEST(UpsampleCloud, ADivergedAdaptationFallsBackToThePlainModel) {
    auto model = small_pugcn(4);
    at::Tensor input = sphere_points(200, 4);
    UpsampleOptions options;
    UpsampleResult plain = upsample_cloud(*model, input, options);
    options.adaptation.inner.steps = 2;
    options.adaptation.inner.step_size = 1e9;
    for (AdaptationUnit unit : {AdaptationUnit::kObject, AdaptationUnit::kPatch}) {
        options.adaptation.unit = unit;
        UpsampleResult blown = upsample_cloud(*model, input, options);
        // (Patch units upsample one patch per pass: equal up to GEMM blocking.)
        EXPECT_TRUE(at::allclose(blown.points, plain.points, 0, 1e-5)) << to_string(unit);
        EXPECT_EQ(blown.loss_after, blown.loss_before) << to_string(unit);
    }
}

TEST(UpsampleCloud, PatchUnitAdaptsEachPatch) {
    auto model = small_pugcn(4);
    UpsampleOptions options;
    options.adaptation.inner.steps = 1;
    options.adaptation.unit = AdaptationUnit::kPatch;
    options.adaptation.inner.step_size = 0.01;
    UpsampleResult result = upsample_cloud(*model, sphere_points(150, 5), options);
    EXPECT_EQ(result.points.size(0), 600);
    EXPECT_TRUE(std::isfinite(result.loss_after));
}

TEST(UpsampleCloud, CloudUnitAdaptsOnTheDownsampledWholeCloud) {
    auto model = small_pugcn(4);
    at::Tensor input = sphere_points(400, 8);
    UpsampleOptions plain;
    UpsampleResult base = upsample_cloud(*model, input, plain);
    UpsampleOptions options;
    options.adaptation.inner.steps = 3;
    options.adaptation.inner.step_size = 0.05;
    options.adaptation.unit = AdaptationUnit::kCloud;
    UpsampleResult cloud = upsample_cloud(*model, input, options);
    EXPECT_EQ(cloud.points.size(0), 1600);
    EXPECT_LT(cloud.loss_after, cloud.loss_before);
    EXPECT_FALSE(cloud.points.equal(base.points));  // θ' differs from θ
    EXPECT_TRUE(cloud.points.equal(upsample_cloud(*model, input, options).points));
    // A different task from the object unit's (patches of X, each downsampled by r).
    options.adaptation.unit = AdaptationUnit::kObject;
    UpsampleResult object = upsample_cloud(*model, input, options);
    EXPECT_GT(std::abs(object.loss_before - cloud.loss_before), 1e-6 * object.loss_before);
    // Too few points to downsample the whole cloud by r.
    options.adaptation.unit = AdaptationUnit::kCloud;
    EXPECT_THROW(upsample_cloud(*model, sphere_points(6, 9), options), InputError);
}

TEST(UpsampleCloud, TtaDownsamplerPicksTheSamplerOfXDown) {
    auto model = make_backbone({{"backbone", "pugcn"},
                                {"ratio", 4},
                                {"channels", 8},
                                {"k", 8},
                                {"upsample_channels", 8},
                                {"reconstruction_channels", 8},
                                {"patch_size", 64},
                                {"downsampler", "fps"},
                                {"seed", 1}});
    at::Tensor input = sphere_points(200, 2);
    UpsampleOptions options;
    options.adaptation.inner.steps = 2;
    options.adaptation.inner.step_size = 0.01;
    for (AdaptationUnit unit :
         {AdaptationUnit::kObject, AdaptationUnit::kCloud, AdaptationUnit::kPatch}) {
        options.adaptation.unit = unit;
        options.adaptation.downsampler.reset();
        UpsampleResult own = upsample_cloud(*model, input, options);
        options.adaptation.downsampler = InputSampler::kFps;  // the backbone's own: the same X↓
        UpsampleResult fps = upsample_cloud(*model, input, options);
        EXPECT_EQ(fps.loss_before, own.loss_before) << to_string(unit);
        EXPECT_TRUE(at::equal(fps.points, own.points)) << to_string(unit);
        options.adaptation.downsampler = InputSampler::kRandom;  // another X↓
        UpsampleResult random = upsample_cloud(*model, input, options);
        EXPECT_NE(random.loss_before, own.loss_before) << to_string(unit);
    }
}

TEST(UpsampleCloud, RatioThatIsNotAPowerOfTheModelsIsAnInputError) {
    auto model = small_pugcn(4);
    UpsampleOptions options;
    options.ratio = 8;
    EXPECT_THROW(upsample_cloud(*model, sphere_points(100, 6), options), InputError);
}

TEST(UpsampleCloud, RatioErrorsNameTheRatiosAModelServesDirectly) {
    auto model = make_backbone(small_backbone_config("metapu"));  // any ratio 2..16
    EXPECT_EQ(output_ratio(*model, 16), 16);                      // its ratio 4, twice
    EXPECT_TRUE(test::throws_input_error([&] { output_ratio(*model, 17); },
                                         {"--ratio", "ratio 17", "serves (2-16)"}));
    EXPECT_TRUE(test::throws_input_error([&] { output_ratio(*small_pugcn(4), 8); },
                                         {"not a power of the model's ratio 4"}));
}

TEST(UpsampleCloud, WholeCloudInferenceRunsTheCloudInItsPartsAtThePatchesSpacing) {
    auto model = small_pugcn(4);
    at::Tensor cloud = sphere_points(300, 8);
    UpsampleOptions options;
    options.whole_cloud_points = 1000;
    UpsampleResult whole = upsample_cloud(*model, cloud, options);
    EXPECT_EQ(whole.points.sizes(), (at::IntArrayRef{1200, 3}));
    EXPECT_EQ(whole.patches, 1);
    EXPECT_TRUE(at::isfinite(whole.points).all().item<bool>());
    options.whole_cloud_points = 100;  // k-d tree parts of at most 100 points
    UpsampleResult parts = upsample_cloud(*model, cloud, options);
    EXPECT_EQ(parts.points.size(0), 1200);
    EXPECT_GE(parts.patches, 3);
    // The outputs stay at the cloud's scale (radius 1): the spacing scale is undone.
    EXPECT_LT(whole.points.norm(2, 1).max().item<double>(), 3.0);
    // Adaptation adapts on the patches, then the whole cloud runs with θ'; a θ' per patch
    // has nothing to run on.
    options.whole_cloud_points = 1000;
    options.adaptation.inner.steps = 1;
    options.adaptation.inner.step_size = 1e-3;
    UpsampleResult adapted = upsample_cloud(*model, cloud, options);
    EXPECT_EQ(adapted.points.size(0), 1200);
    EXPECT_TRUE(std::isfinite(adapted.loss_after));
    EXPECT_FALSE(adapted.points.equal(whole.points));
    options.adaptation.unit = AdaptationUnit::kPatch;
    EXPECT_TRUE(test::throws_input_error([&] { upsample_cloud(*model, cloud, options); },
                                         {"--tta-unit", "whole-cloud"}));
    // 0: patches, whatever the backbone prefers.
    options = UpsampleOptions{};
    options.whole_cloud_points = 0;
    EXPECT_GT(upsample_cloud(*model, cloud, options).patches, 1);
}

/// n evenly spread points on the unit sphere (a Fibonacci lattice).
at::Tensor fibonacci_sphere(int64_t n) {
    at::Tensor i = at::arange(n, at::kDouble) + 0.5;
    at::Tensor z = 1 - 2 * i / double(n);
    at::Tensor r = at::sqrt(1 - z * z);
    at::Tensor phi = i * (M_PI * (3 - std::sqrt(5.0)));
    return at::stack({r * at::cos(phi), r * at::sin(phi), z}, 1).to(at::kFloat);
}

/// A scan-like cloud: a dense cluster beside sparse points (spacing spread far above the
/// threshold).
at::Tensor scan_like(int64_t dense, int64_t sparse, uint64_t seed) {
    return at::cat({sphere_points(sparse, seed), sphere_points(dense, seed + 1) * 0.05 + 0.5});
}

TEST(UpsampleCloud, SpacingSpreadSeparatesEvenSamplesFromScans) {
    EXPECT_LT(spacing_spread(fibonacci_sphere(500)), 1.5);
    // Uniformly random points on a surface (a random subset of a scan of it) stay below.
    EXPECT_LT(spacing_spread(sphere_points(2000, 11)), kScanSpacingSpread);
    EXPECT_GT(spacing_spread(scan_like(400, 200, 9)), 2 * kScanSpacingSpread);
    EXPECT_EQ(spacing_spread(at::zeros({2, 3})), 1.0);
    EXPECT_EQ(spacing_spread(at::zeros({5, 3})), 1.0);  // all coincident
}

/// A random 1/4 of an airborne-like sweep: a 120 x 120 grid of spacing 0.5 on the plane z = 0
/// with a block (a raised roof) and Gaussian height noise `sigma`.
at::Tensor gridded_returns(double sigma, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::Tensor t = at::arange(120, at::kFloat) * 0.5f;
    std::vector<at::Tensor> xy = at::meshgrid({t, t}, "ij");
    at::Tensor x = xy[0].flatten(), y = xy[1].flatten();
    at::Tensor roof = ((x > 20) & (x < 35) & (y > 10) & (y < 30)).to(at::kFloat) * 6.0f;
    at::Tensor z = roof + sigma * at::randn({x.size(0)}, gen);
    at::Tensor all = at::stack({x, y, z}, 1);
    return all.index_select(0, at::randperm(all.size(0), gen).narrow(0, 0, all.size(0) / 4));
}

TEST(UpsampleCloud, SurfaceThicknessIsSmallOnPlanesAndGrowsWithNoise) {
    EXPECT_LT(surface_thickness(gridded_returns(0.0, 1)), 0.02);
    EXPECT_LT(surface_thickness(gridded_returns(0.05, 1)), kMeasuredThickness);
    EXPECT_GT(surface_thickness(gridded_returns(0.5, 1)), 2 * kMeasuredThickness);
    // At the spacing of 100 points a sphere is curved: thick against the spacing (the sag of
    // a neighbourhood grows as the spacing squared, so the ratio falls as points are added).
    const double coarse = surface_thickness(fibonacci_sphere(100));
    EXPECT_GT(coarse, kMeasuredThickness);
    EXPECT_LT(surface_thickness(fibonacci_sphere(2000)), coarse / 2);
    EXPECT_EQ(surface_thickness(at::zeros({8, 3})), 0.0);
    EXPECT_EQ(surface_thickness(at::zeros({40, 3})), 0.0);  // all coincident
}

TEST(UpsampleCloud, SurfaceRoughnessIsSmallOnNoiseFreeCurvedPointsAndGrowsWithNoise) {
    // 300 random points on a sphere: curved at their spacing (thick), yet on a quadric.
    at::Tensor exact = sphere_points(300, 13);
    EXPECT_GT(surface_thickness(exact), kMeasuredThickness);
    EXPECT_LT(surface_roughness(exact), kExactRoughness / 3);
    at::Generator gen = at::detail::createCPUGenerator(14);
    at::Tensor noisy = exact + 0.02f * at::randn(exact.sizes(), gen);  // about 0.2 spacings
    EXPECT_GT(surface_roughness(noisy), 2 * kExactRoughness);
    EXPECT_LT(surface_roughness(gridded_returns(0.0, 1)), kExactRoughness / 3);
    EXPECT_GT(surface_roughness(gridded_returns(0.5, 1)), 2 * kExactRoughness);
    // Large clouds are measured on a strided subset: still near 0 when noise-free.
    EXPECT_LT(surface_roughness(sphere_points(120'000, 15)), kExactRoughness / 3);
    EXPECT_EQ(surface_roughness(at::zeros({8, 3})), 0.0);
    EXPECT_EQ(surface_roughness(at::zeros({40, 3})), 0.0);  // all coincident
}

TEST(UpsampleCloud, ClassifiesEvenSamplesMeasuredReturnsAndScans) {
    EXPECT_EQ(classify_input(fibonacci_sphere(500)), InputKind::kSampled);
    EXPECT_EQ(classify_input(gridded_returns(0.05, 2)), InputKind::kMeasured);
    // Irregular but noisy across the surface as much as along it: a sample, not returns.
    EXPECT_EQ(classify_input(gridded_returns(0.5, 2)), InputKind::kSampled);
    // Noise-free random points on a curved surface (a random subset of a dense sample): thick
    // at their spacing, but on it; with noise, a sample.
    at::Tensor subset = sphere_points(300, 13);
    ASSERT_GT(spacing_spread(subset), kMeasuredSpacingSpread);
    EXPECT_EQ(classify_input(subset), InputKind::kMeasured);
    at::Generator gen = at::detail::createCPUGenerator(14);
    EXPECT_EQ(classify_input(subset + 0.02f * at::randn(subset.sizes(), gen)), InputKind::kSampled);
    EXPECT_EQ(classify_input(scan_like(400, 200, 9)), InputKind::kScan);
    EXPECT_STREQ(input_kind_name(InputKind::kMeasured), "measured");
}

TEST(UpsampleCloud, KeepsTheInputPointsOfScansByDefault) {
    auto model = small_pugcn(4);
    auto contains_input = [](const at::Tensor& out, const at::Tensor& in) {
        // Up to the round trip through the unit-sphere frame.
        return knn(out, in, 1).sq_distances.max().item<double>() < 1e-10;
    };
    UpsampleOptions options;
    at::Tensor scan = scan_like(300, 100, 10);
    UpsampleResult automatic = upsample_cloud(*model, scan, options);
    EXPECT_EQ(automatic.points.size(0), 1600);
    EXPECT_TRUE(contains_input(automatic.points, scan));
    options.keep_input = false;
    EXPECT_FALSE(contains_input(upsample_cloud(*model, scan, options).points, scan));
    // Measured returns (aerial-like) keep theirs too.
    at::Tensor returns = gridded_returns(0.05, 3).narrow(0, 0, 400);
    ASSERT_EQ(classify_input(returns), InputKind::kMeasured);
    EXPECT_TRUE(contains_input(upsample_cloud(*model, returns, UpsampleOptions{}).points, returns));
    // An even sample keeps only network points unless asked.
    at::Tensor even = fibonacci_sphere(300);
    EXPECT_FALSE(contains_input(upsample_cloud(*model, even, UpsampleOptions{}).points, even));
    options.keep_input = true;
    UpsampleResult kept = upsample_cloud(*model, even, options);
    EXPECT_EQ(kept.points.size(0), 1200);
    EXPECT_TRUE(contains_input(kept.points, even));
}

TEST(UpsampleCloud, IrregularInputsPickByFpsAtAnySizeOthersByTheBudget) {
    auto model = small_pugcn(4);
    auto run = [&](const at::Tensor& cloud, std::optional<Selection> selection) {
        UpsampleOptions options;
        options.fps_budget = 1e5;  // as if the clouds were large
        options.selection = selection;
        return upsample_cloud(*model, cloud, options).points;
    };
    // Uniformly random points on a surface (a random subset of an even sample): FPS.
    at::Tensor irregular = sphere_points(400, 12);
    ASSERT_GT(spacing_spread(irregular), kMeasuredSpacingSpread);
    ASSERT_LT(spacing_spread(irregular), kScanSpacingSpread);
    at::Tensor fps = run(irregular, Selection::kFps);
    EXPECT_EQ(fps.size(0), 1600);
    EXPECT_TRUE(run(irregular, std::nullopt).equal(fps));
    EXPECT_FALSE(run(irregular, Selection::kOwnership).equal(fps));
    // An even sample beyond the budget: ownership, whose picks lie closer together.
    at::Tensor even = fibonacci_sphere(400);
    at::Tensor ownership = run(even, Selection::kOwnership);
    EXPECT_EQ(ownership.size(0), 1600);
    EXPECT_TRUE(run(even, std::nullopt).equal(ownership));
    auto least_spacing = [](const at::Tensor& points) {
        return knn(points, points, 2).sq_distances.select(1, 1).min().item<double>();
    };
    EXPECT_GT(least_spacing(run(even, Selection::kFps)), least_spacing(ownership));
}

TEST(UpsampleCloud, LineProjectionPutsOutputsOnTheLinesOfLineLikeInputs) {
    auto model = small_pugcn(4);
    // Two parallel lines of 150 points each, 0.5 apart: every neighbourhood is line-like.
    at::Tensor t = at::linspace(-1, 1, 150);
    at::Tensor zero = at::zeros({150});
    at::Tensor lines =
        at::cat({at::stack({t, zero, zero}, 1), at::stack({t, zero + 0.5, zero}, 1)});
    UpsampleOptions options;
    options.line_projection = 0.3;
    at::Tensor out = upsample_cloud(*model, lines, options).points;
    ASSERT_EQ(out.size(0), 1200);
    at::Tensor y = out.select(1, 1), z = out.select(1, 2);
    at::Tensor off_line = at::minimum(y.abs(), (y - 0.5).abs());
    EXPECT_LT(off_line.max().item<double>(), 1e-4);
    EXPECT_LT(z.abs().max().item<double>(), 1e-4);
    // Without it the network's points leave the lines.
    options.line_projection = 0.0;
    at::Tensor free = upsample_cloud(*model, lines, options).points;
    EXPECT_GT(
        at::minimum(free.select(1, 1).abs(), (free.select(1, 1) - 0.5).abs()).max().item<double>(),
        1e-3);
}

/// 2,048 Poisson-disk points of a procedural mesh, as the PU-GAN test inputs are made.
at::Tensor pugan_like_input(uint64_t seed, int64_t n = 2048) {
    return sample_poisson_disk(generate_shape(seed), n, seed + 1).points;
}

// The published baseline on a PU-GAN-like input: every one of the r·N points distinct (the
// candidate pool of midpoints from the 2r nearest holds repeats, since a pair of mutual
// neighbours gives one midpoint twice, and FPS once padded the output with one of them), the
// centroid where the input's is, and closer to a dense sample of the surface than the input.
TEST(MidpointUpsample, PuganLikeInputGivesDistinctPointsAroundTheSameCentroid) {
    const TriangleMesh mesh = generate_shape(3);
    const at::Tensor input = sample_poisson_disk(mesh, 2048, 4).points;
    for (int64_t r : {4, 16}) {
        at::Tensor out = midpoint_upsample(input, r);
        ASSERT_EQ(out.size(0), r * 2048) << r;
        EXPECT_EQ(count_distinct_points(out), r * 2048) << r;
        const double radius = (input - input.mean(0)).norm(2, 1).max().item<double>();
        EXPECT_LT((out.mean(0) - input.mean(0)).norm().item<double>(), 0.01 * radius) << r;
        const at::Tensor dense = sample_poisson_disk(mesh, r * 2048, 5).points;
        EXPECT_LT(chamfer_distance(out, dense), 0.75 * chamfer_distance(input, dense)) << r;
    }
}

// Where the candidates hold fewer distinct points than asked for (few neighbours), midpoints
// between them make more instead of repeats; only an input that repeats its points repeats.
TEST(MidpointUpsample, TooFewCandidatesAreJoinedByMoreMidpointsNotRepeats) {
    const at::Tensor input = sphere_points(200, 11);
    at::Tensor out = midpoint_upsample(input, 8, /*k=*/1);
    ASSERT_EQ(out.size(0), 1600);
    EXPECT_EQ(count_distinct_points(out), 1600);
    const at::Tensor one_place = at::zeros({5, 3}, at::kFloat);
    EXPECT_EQ(midpoint_upsample(one_place, 4).size(0), 20);
}

// The network path: whichever way the count is reached (FPS, the ownership merge, with or
// without the input kept, whole-cloud inference), no position is returned twice.
TEST(UpsampleCloud, NoPathRepeatsAPoint) {
    auto model = small_pugcn(4);
    const at::Tensor input = pugan_like_input(7, 600);
    struct Case {
        const char* name;
        Selection selection;
        bool keep_input;
        int64_t whole_cloud;
    };
    for (const Case& c :
         {Case{"fps", Selection::kFps, false, 0}, Case{"fps keep-input", Selection::kFps, true, 0},
          Case{"ownership", Selection::kOwnership, false, 0},
          Case{"ownership keep-input", Selection::kOwnership, true, 0},
          Case{"whole cloud", Selection::kFps, false, 1 << 20},
          Case{"whole cloud keep-input", Selection::kOwnership, true, 1 << 20}}) {
        UpsampleOptions options;
        options.selection = c.selection;
        options.keep_input = c.keep_input;
        if (c.whole_cloud) options.whole_cloud_points = c.whole_cloud;
        const at::Tensor out = upsample_cloud(*model, input, options).points;
        ASSERT_EQ(out.size(0), 2400) << c.name;
        EXPECT_EQ(count_distinct_points(out), 2400) << c.name;
    }
}

TEST(MidpointUpsample, ExactCountAndPointsBetweenNeighbours) {
    at::Tensor input = sphere_points(500, 7);
    at::Tensor out = midpoint_upsample(input, 4);
    EXPECT_EQ(out.size(0), 2000);
    // Midpoints of near neighbours on the unit sphere lie just inside it.
    at::Tensor radius = out.norm(2, 1);
    EXPECT_LE(radius.max().item<float>(), 1.0f + 1e-5f);
    EXPECT_GT(radius.min().item<float>(), 0.9f);
    // Denser than the input: closer to a dense sample of the same sphere.
    at::Tensor dense = sphere_points(2000, 8);
    EXPECT_LT(chamfer_distance(out, dense), chamfer_distance(input, dense));
}

// Large clouds, where FPS would be quadratic, are thinned by sample elimination instead: the
// same count, and as close to a dense sample as FPS's choice (within 10 %).
TEST(MidpointUpsample, SampleEliminationReplacesFpsBeyondItsBudget) {
    at::Tensor input = sphere_points(3000, 9);
    at::Tensor fps = midpoint_upsample(input, 4, 0);
    at::Tensor eliminated = midpoint_upsample(input, 4, 0, /*fps_budget=*/0);
    ASSERT_EQ(eliminated.size(0), 12000);
    at::Tensor dense = sphere_points(12000, 10);
    const double cd_fps = chamfer_distance(fps, dense);
    const double cd_eliminated = chamfer_distance(eliminated, dense);
    EXPECT_LT(cd_eliminated, 1.1 * cd_fps) << cd_fps;
    EXPECT_LT(cd_eliminated, chamfer_distance(input, dense));
    // Every output is one of the candidates: an input point or a midpoint, inside the sphere.
    EXPECT_LE(eliminated.norm(2, 1).max().item<float>(), 1.0f + 1e-5f);
    // Duplicated inputs (zero spacing) still give the exact count.
    at::Tensor doubled = at::cat({input.slice(0, 0, 10), input.slice(0, 0, 10)});
    EXPECT_EQ(midpoint_upsample(doubled, 4, 0, 0).size(0), 80);
}

TEST(UpsampleCloud, EveryBackboneGivesTheSameBitsOnOneTwoThreeAndEightThreads) {
    // Batches of a fixed composition run concurrently, each on one thread: the output may not
    // depend on the thread count, plain or adapted (one θ' per object, or one per patch).
    const int previous = at::get_num_threads();
    const at::Tensor input = sample_uniform(generate_shape(5), 300, 1).points;
    for (const std::string& name : registered_backbones()) {
        auto model = make_backbone(small_backbone_config(name));
        for (const char* mode : {"plain", "object", "patch"}) {
            UpsampleOptions options;
            options.batch_patches = 3;
            if (std::string(mode) != "plain") {
                options.adaptation.inner.steps = 1;
                options.adaptation.inner.step_size = 1e-3;
                options.adaptation.unit = std::string(mode) == "object" ? AdaptationUnit::kObject
                                                                        : AdaptationUnit::kPatch;
            }
            at::Tensor first;
            for (int threads : {1, 2, 3, 8}) {
                at::set_num_threads(threads);
                at::Tensor points;
                try {
                    points = upsample_cloud(*model, input, options).points;
                } catch (const InputError& e) {
                    // A backbone with its own whole-cloud pipeline has no per-patch unit.
                    ASSERT_STREQ(mode, "patch") << name << ": " << e.what();
                    break;
                }
                if (!first.defined()) {
                    first = points;
                    EXPECT_GT(points.size(0), 0) << name;
                } else {
                    EXPECT_TRUE(points.equal(first))
                        << name << ", " << mode << ", " << threads << " threads";
                }
            }
        }
    }
    at::set_num_threads(previous);
}

}  // namespace
}  // namespace pumeta
