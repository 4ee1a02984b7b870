// Quantisation of points onto voxels and back.
#include "pumeta/nn/sparse/voxelize.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

TEST(Voxelize, FloorsEachCoordinateIncludingNegatives) {
    at::Tensor points = at::tensor({0.05f, -0.05f, 0.25f, -0.35f, 0.0f, 0.099f}).view({1, 2, 3});
    at::Tensor c = voxel_coordinates(points, 0.1);
    at::Tensor expected = at::tensor({0, 0, -1, 2, 0, -4, 0, 0}, at::kLong).view({2, 4});
    EXPECT_TRUE(c.equal(expected)) << c;
}

TEST(Voxelize, KeepsOneSitePerOccupiedVoxelPerBatchElement) {
    at::Tensor cloud = uniform_random_points(500, 1);
    at::Tensor batch = at::stack({cloud, cloud.flip(0)});  // same voxels, other element
    const double h = 0.25;
    CoordinateSetPtr set = voxelize(batch, h);
    std::set<std::array<int64_t, 3>> occupied;
    for (int64_t i = 0; i < cloud.size(0); ++i)
        occupied.insert({int64_t(std::floor(cloud[i][0].item<double>() / h)),
                         int64_t(std::floor(cloud[i][1].item<double>() / h)),
                         int64_t(std::floor(cloud[i][2].item<double>() / h))});
    EXPECT_EQ(set->size(), 2 * int64_t(occupied.size()));
    EXPECT_EQ(set->batch_size(), 2);
    EXPECT_EQ((set->batch_index() == 1).sum().item<int64_t>(), int64_t(occupied.size()));
}

TEST(Voxelize, CentresLieInTheirVoxelWithinHalfAnEdgeOfThePoints) {
    at::Tensor cloud = uniform_random_points(300, 2).unsqueeze(0);
    const double h = 0.1;
    at::Tensor coords = voxel_coordinates(cloud, h);
    at::Tensor centres = voxel_centres(coords, h);
    EXPECT_LE((centres - cloud[0]).abs().max().item<double>(), 0.5 * h + 1e-6);
    // Voxelising the centres gives the same voxels back.
    EXPECT_TRUE(voxel_coordinates(centres.unsqueeze(0), h).equal(coords));
}

TEST(Voxelize, RejectsBadVoxelSizesAndNonFinitePoints) {
    at::Tensor cloud = uniform_random_points(10, 3).unsqueeze(0);
    EXPECT_THROW(voxelize(cloud, 0.0), InputError);
    EXPECT_THROW(voxelize(cloud, 1e-6), InputError);  // beyond the 16-bit coordinate range
    cloud[0][3][1] = std::nanf("");
    EXPECT_THROW(voxelize(cloud, 0.1), InputError);
}

}  // namespace
}  // namespace pumeta
