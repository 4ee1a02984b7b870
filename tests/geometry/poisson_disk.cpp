#include <ATen/ATen.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "geometry/mesh_oracles.h"
#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"

namespace pumeta {
namespace {

/// Weighted sample elimination done the slow, obvious way: recompute every weight from
/// scratch, remove the heaviest sample (ties: the larger index), repeat until n remain.
std::vector<int64_t> naive_elimination(const at::Tensor& candidates, int64_t n, double area) {
    const double r_max = 2 * std::sqrt(area / n / (2 * std::sqrt(3.0)));
    const double radius = 2 * r_max;
    auto p = candidates.accessor<float, 2>();
    const int64_t count = candidates.size(0);
    std::vector<bool> alive(count, true);
    for (int64_t remaining = count; remaining > n; --remaining) {
        int64_t heaviest = -1;
        double heaviest_weight = -1;
        for (int64_t i = 0; i < count; ++i) {
            if (!alive[i]) continue;
            double weight = 0;
            for (int64_t j = 0; j < count; ++j) {
                if (!alive[j] || j == i) continue;
                double d = 0;
                for (int axis = 0; axis < 3; ++axis)
                    d += std::pow(double(p[i][axis]) - p[j][axis], 2);
                d = std::sqrt(d);
                if (d < radius) weight += std::pow(1 - d / radius, 8);
            }
            if (weight >= heaviest_weight) heaviest_weight = weight, heaviest = i;
        }
        alive[heaviest] = false;
    }
    std::vector<int64_t> kept;
    for (int64_t i = 0; i < count; ++i)
        if (alive[i]) kept.push_back(i);
    return kept;
}

/// Distance from each point to its nearest other point (brute force).
at::Tensor nearest_neighbour_distances(const at::Tensor& points) {
    at::Tensor d = at::cdist(points.to(at::kDouble), points.to(at::kDouble));
    d.fill_diagonal_(std::numeric_limits<double>::infinity());
    return std::get<0>(d.min(1));
}

TEST(PoissonDisk, ExactCountOnTheMeshWithFaceNormals) {
    TriangleMesh cube = test::unit_cube();
    PointCloud cloud = sample_poisson_disk(cube, 500, 1);
    ASSERT_EQ(cloud.points.sizes(), (at::IntArrayRef{500, 3}));
    ASSERT_EQ(cloud.normals.sizes(), (at::IntArrayRef{500, 3}));
    auto p = cloud.points.accessor<float, 2>();
    auto n = cloud.normals.accessor<float, 2>();
    for (int64_t i = 0; i < 500; ++i) {
        auto [face, distance] = test::nearest_face(cube, {p[i][0], p[i][1], p[i][2]});
        EXPECT_LT(distance, 1e-5);
        EXPECT_NEAR(test::dot(test::face_normal(cube, face), {n[i][0], n[i][1], n[i][2]}), 1.0,
                    1e-6);
    }
}

TEST(PoissonDisk, EqualsNaiveEliminationOfTheUniformCandidates) {
    TriangleMesh cube = test::unit_cube();
    for (uint64_t seed : {2, 3}) {
        const int64_t n = 80;
        at::Tensor candidates = sample_uniform(cube, 5 * n, seed).points;
        at::Tensor expected =
            candidates.index_select(0, at::tensor(naive_elimination(candidates, n, /*area=*/6.0)));
        EXPECT_TRUE(at::equal(sample_poisson_disk(cube, n, seed).points, expected))
            << "seed " << seed;
    }
}

TEST(PoissonDisk, SpacingIsMoreRegularThanUniformSampling) {
    TriangleMesh cube = test::unit_cube();
    at::Tensor poisson = nearest_neighbour_distances(sample_poisson_disk(cube, 1000, 4).points);
    at::Tensor uniform = nearest_neighbour_distances(sample_uniform(cube, 1000, 4).points);
    const double poisson_mean = poisson.mean().item<double>();
    const double uniform_mean = uniform.mean().item<double>();
    // A uniform (Poisson process) sample has NN distances with CV about 0.52 and a minimum
    // near 0; blue noise is tighter around a larger spacing.
    EXPECT_GT(poisson_mean, 1.4 * uniform_mean);
    EXPECT_LT(poisson.std().item<double>() / poisson_mean,
              0.3 * uniform.std().item<double>() / uniform_mean);
    EXPECT_GT(poisson.min().item<double>(), 0.6 * poisson_mean);
    EXPECT_LT(uniform.min().item<double>(), 0.1 * uniform_mean);
}

TEST(PoissonDisk, SeededAndValidated) {
    TriangleMesh cube = test::unit_cube();
    at::Tensor first = sample_poisson_disk(cube, 200, 5).points;
    EXPECT_TRUE(at::equal(first, sample_poisson_disk(cube, 200, 5).points));
    EXPECT_FALSE(at::equal(first, sample_poisson_disk(cube, 200, 6).points));
    // Without extra candidates nothing is eliminated: the uniform samples themselves.
    EXPECT_TRUE(at::equal(sample_poisson_disk(cube, 200, 5, {/*init_factor=*/1}).points,
                          sample_uniform(cube, 200, 5).points));
    EXPECT_EQ(sample_poisson_disk(cube, 0, 5).size(), 0);
    EXPECT_THROW(sample_poisson_disk(cube, 10, 5, {/*init_factor=*/0}), InputError);
    EXPECT_THROW(sample_poisson_disk(cube, -1, 5), InputError);
}

}  // namespace
}  // namespace pumeta
