// The patch pipeline's patches: seeds by FPS, part by part on large clouds, then more seeds
// until every point lies in a patch.
#include "pumeta/geometry/patches.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/geometry/kdtree_partition.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

/// Points of the cloud [N,3] in no patch.
int64_t uncovered(const at::Tensor& cloud, const Patches& patches) {
    at::Tensor covered = at::zeros({cloud.size(0)}, at::kBool);
    covered.index_fill_(0, patches.indices.flatten(), true);
    return (~covered).sum().item<int64_t>();
}

/// The largest distance from a point of the cloud to its nearest seed.
double covering_radius(const at::Tensor& cloud, const at::Tensor& seeds) {
    return knn(cloud.index_select(0, seeds), cloud, 1).sq_distances.sqrt().max().item<double>();
}

TEST(ExtractPatches, SmallCloudsTakeFpsSeedsOverTheWholeCloud) {
    at::Tensor cloud = uniform_random_points(1000, 3);
    Patches patches = extract_patches(cloud, {.patch_size = 64, .coverage = 3.0});
    // ceil(1000 / 64 · 3) = 47 by FPS first, then a few for the points they miss.
    const int64_t count = patches.seeds.numel();
    ASSERT_GE(count, 47);
    EXPECT_LE(count, 47 + 5);
    EXPECT_TRUE(at::equal(patches.seeds.narrow(0, 0, 47), farthest_point_sampling(cloud, 47, 0)));
    EXPECT_EQ(patches.points.sizes(), (std::vector<int64_t>{count, 64, 3}));
    EXPECT_EQ(uncovered(cloud, patches), 0);
    EXPECT_NEAR(patches.points.norm(2, 2).amax(1).min().item<double>(), 1.0, 1e-5);
}

TEST(ExtractPatches, LargeCloudsTakeSeedsPartByPartAsEvenlyAsWholeCloudFps) {
    at::Tensor cloud = uniform_random_points(6000, 4);
    PatchOptions options{.patch_size = 64, .coverage = 3.0, .fps_part_points = 1000};
    Patches patches = extract_patches(cloud, options);
    const int64_t count = 282;  // ceil(6000 / 64 · 3), then a few for the points they miss
    ASSERT_GE(patches.seeds.numel(), count);
    EXPECT_LE(patches.seeds.numel(), count + 15);
    EXPECT_EQ(std::get<0>(at::_unique(patches.seeds)).numel(), patches.seeds.numel());
    EXPECT_EQ(uncovered(cloud, patches), 0);
    patches.seeds = patches.seeds.narrow(0, 0, count);
    // Each k-d tree part has seeds in proportion to its size (8 parts of 750 points).
    for (const at::Tensor& part : kdtree_partition(cloud, 1000)) {
        int64_t inside = at::isin(patches.seeds, part).sum().item<int64_t>();
        EXPECT_NEAR(double(inside), double(count) * part.numel() / 6000, 1.0);
    }
    // As even as FPS over the whole cloud, up to part borders.
    EXPECT_LT(covering_radius(cloud, patches.seeds),
              1.5 * covering_radius(cloud, farthest_point_sampling(cloud, count, 0)));
}

TEST(ExtractPatches, EveryPointOfACloudWithVaryingDensityLiesInAPatch) {
    // A scan-like cloud: 4,000 points in a small dense cluster, 1,000 spread over a cube 100
    // times wider. Seeds spread evenly in space put only a few patches in the cluster.
    at::Tensor dense = uniform_random_points(4000, 5) * 0.01;
    at::Tensor sparse = uniform_random_points(1000, 6);
    at::Tensor cloud = at::cat({sparse, dense});
    const int64_t fps_seeds = 79;  // ceil(5000 / 64 · 1)
    at::Tensor first = farthest_point_sampling(cloud, fps_seeds, 0);
    Patches fps_only;
    fps_only.indices = knn(cloud, cloud.index_select(0, first), 64).indices;
    ASSERT_GT(uncovered(cloud, fps_only), 2000) << "the case the filling is for";
    Patches patches = extract_patches(cloud, {.patch_size = 64, .coverage = 1.0});
    EXPECT_EQ(uncovered(cloud, patches), 0);
    EXPECT_TRUE(at::equal(patches.seeds.narrow(0, 0, fps_seeds), first));
    // A few more patches per 64 points it missed (they overlap), not one per point.
    EXPECT_LT(patches.seeds.numel(), fps_seeds + 3 * (4000 / 64));
    EXPECT_EQ(patches.points.size(0), patches.seeds.numel());
}

TEST(ExtractPatches, ExactDuplicatesBeyondAPatchStillEnd) {
    // 300 copies of one point: a seed's 64 nearest are copies with smaller indices.
    at::Tensor cloud = at::cat({uniform_random_points(100, 7), at::zeros({300, 3})});
    Patches patches = extract_patches(cloud, {.patch_size = 64, .coverage = 1.0});
    EXPECT_GE(patches.seeds.numel(), 7);
    EXPECT_EQ(patches.points.size(1), 64);
}

}  // namespace
}  // namespace pumeta
