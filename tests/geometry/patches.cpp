// The patch pipeline's patches: seeds by FPS, part by part on large clouds.
#include "pumeta/geometry/patches.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/geometry/kdtree_partition.h"
#include "pumeta/geometry/knn.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

/// The largest distance from a point of the cloud to its nearest seed.
double covering_radius(const at::Tensor& cloud, const at::Tensor& seeds) {
    return knn(cloud.index_select(0, seeds), cloud, 1).sq_distances.sqrt().max().item<double>();
}

TEST(ExtractPatches, SmallCloudsTakeFpsSeedsOverTheWholeCloud) {
    at::Tensor cloud = uniform_random_points(1000, 3);
    Patches patches = extract_patches(cloud, {.patch_size = 64, .coverage = 3.0});
    EXPECT_EQ(patches.seeds.numel(), 47);  // ceil(1000 / 64 · 3)
    EXPECT_TRUE(at::equal(patches.seeds, farthest_point_sampling(cloud, 47, 0)));
    EXPECT_EQ(patches.points.sizes(), (std::vector<int64_t>{47, 64, 3}));
    EXPECT_NEAR(patches.points.norm(2, 2).amax(1).min().item<double>(), 1.0, 1e-5);
}

TEST(ExtractPatches, LargeCloudsTakeSeedsPartByPartAsEvenlyAsWholeCloudFps) {
    at::Tensor cloud = uniform_random_points(6000, 4);
    PatchOptions options{.patch_size = 64, .coverage = 3.0, .fps_part_points = 1000};
    Patches patches = extract_patches(cloud, options);
    const int64_t count = 282;  // ceil(6000 / 64 · 3)
    ASSERT_EQ(patches.seeds.numel(), count);
    EXPECT_EQ(std::get<0>(at::_unique(patches.seeds)).numel(), count);
    // Each k-d tree part has seeds in proportion to its size (8 parts of 750 points).
    for (const at::Tensor& part : kdtree_partition(cloud, 1000)) {
        int64_t inside = at::isin(patches.seeds, part).sum().item<int64_t>();
        EXPECT_NEAR(double(inside), double(count) * part.numel() / 6000, 1.0);
    }
    // As even as FPS over the whole cloud, up to part borders.
    EXPECT_LT(covering_radius(cloud, patches.seeds),
              1.5 * covering_radius(cloud, farthest_point_sampling(cloud, count, 0)));
}

}  // namespace
}  // namespace pumeta
