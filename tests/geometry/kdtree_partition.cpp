// The KD-tree partition of large clouds against its defining properties.
#include "pumeta/geometry/kdtree_partition.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

TEST(KdtreePartition, PartsAreSmallDisjointAndCoverTheCloud) {
    at::Tensor points = uniform_random_points(10007, 1);
    for (int64_t limit : {1, 100, 2500, 10007, 70000}) {
        auto parts = kdtree_partition(points, limit);
        at::Tensor hits = at::zeros({points.size(0)}, at::kLong);
        for (const at::Tensor& part : parts) {
            EXPECT_LE(part.numel(), limit);
            EXPECT_GT(part.numel(), 0);
            hits.index_add_(0, part, at::ones({part.numel()}, at::kLong));
        }
        EXPECT_TRUE((hits == 1).all().item<bool>()) << "limit " << limit;
        if (limit >= points.size(0)) EXPECT_EQ(parts.size(), 1u);
    }
}

TEST(KdtreePartition, SplitsAtTheMedianOfTheWidestAxis) {
    // Stretched along y: the first split is a plane y = median, halves of equal size.
    at::Tensor points = uniform_random_points(1000, 2) * at::tensor({1.0f, 10.0f, 1.0f});
    auto parts = kdtree_partition(points, 500);
    ASSERT_EQ(parts.size(), 2u);
    EXPECT_EQ(parts[0].numel(), 500);
    at::Tensor y0 = points.index_select(0, parts[0]).select(1, 1);
    at::Tensor y1 = points.index_select(0, parts[1]).select(1, 1);
    EXPECT_LE(y0.max().item<float>(), y1.min().item<float>());
    // Four parts of 250 for a limit of 300: two levels of halving.
    auto quarters = kdtree_partition(points, 300);
    ASSERT_EQ(quarters.size(), 4u);
    for (const at::Tensor& q : quarters) EXPECT_EQ(q.numel(), 250);
}

TEST(KdtreePartition, RejectsInvalidLimits) {
    EXPECT_THROW(kdtree_partition(uniform_random_points(10, 3), 0), InputError);
}

}  // namespace
}  // namespace pumeta
