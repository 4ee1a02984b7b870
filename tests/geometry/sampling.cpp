#include "pumeta/geometry/sampling.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <vector>

#include "geometry/mesh_oracles.h"
#include "pumeta/core/error.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

/// Textbook FPS: each new point maximises its distance to the nearest point chosen so far
/// (recomputed from scratch, O(N m^2)); ties go to the smaller index. Arithmetic in the
/// points' own precision.
template <typename Scalar>
std::vector<int64_t> naive_fps(const at::Tensor& points, int64_t m, int64_t start) {
    auto p = points.accessor<Scalar, 2>();
    auto sq_distance = [&](int64_t i, int64_t j) {
        const Scalar dx = p[i][0] - p[j][0], dy = p[i][1] - p[j][1], dz = p[i][2] - p[j][2];
        return dx * dx + dy * dy + dz * dz;
    };
    std::vector<int64_t> chosen{start};
    while (static_cast<int64_t>(chosen.size()) < m) {
        int64_t best = -1;
        Scalar best_distance = -1;
        for (int64_t i = 0; i < points.size(0); ++i) {
            Scalar nearest = std::numeric_limits<Scalar>::infinity();
            for (int64_t c : chosen) nearest = std::min(nearest, sq_distance(i, c));
            if (nearest > best_distance) best_distance = nearest, best = i;
        }
        chosen.push_back(best);
    }
    return chosen;
}

std::vector<int64_t> to_vector(const at::Tensor& indices) {
    at::Tensor cpu = indices.contiguous();
    return {cpu.data_ptr<int64_t>(), cpu.data_ptr<int64_t>() + cpu.numel()};
}

TEST(UniformRandomPoints, FillTheCubeAndRepeatPerSeed) {
    at::Tensor a = uniform_random_points(20000, 5);
    ASSERT_EQ(a.sizes(), (at::IntArrayRef{20000, 3}));
    EXPECT_EQ(a.scalar_type(), at::kFloat);
    EXPECT_LE(a.abs().max().item<float>(), 1.f);
    // Uniform on [-1, 1]: per coordinate mean 0 and variance 1/3, within sampling error.
    EXPECT_LT(a.mean(0).abs().max().item<float>(), 0.02f);
    EXPECT_LT((a.var(0) - 1.0 / 3).abs().max().item<float>(), 0.02f);
    EXPECT_TRUE(a.equal(uniform_random_points(20000, 5)));
    EXPECT_FALSE(a.equal(uniform_random_points(20000, 6)));
    EXPECT_THROW(uniform_random_points(-1, 5), InputError);
}

TEST(FarthestPointSampling, EqualsTheTextbookAlgorithm) {
    at::Tensor points = uniform_random_points(2000, 1);
    for (int64_t start : {0, 17, 1999}) {
        const std::vector<int64_t> textbook = naive_fps<float>(points, 150, start);
        EXPECT_EQ(to_vector(farthest_point_sampling(points, 150, start)), textbook);
        EXPECT_EQ(to_vector(farthest_point_sampling_pruned(points, 150, start)), textbook);
    }
}

TEST(FarthestPointSampling, ParallelPathEqualsTheTextbookAlgorithm) {
    // More points than one parallel chunk.
    at::Tensor points = uniform_random_points(40000, 2);
    EXPECT_EQ(to_vector(farthest_point_sampling(points, 25, 5)), naive_fps<float>(points, 25, 5));
}

TEST(FarthestPointSampling, TiesGoToTheSmallerIndex) {
    // Corners of a square: after corner 0, corner 3 is farthest; then 1 and 2 tie.
    at::Tensor points =
        at::tensor({0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 1.f, 1.f, 0.f}).view({4, 3});
    EXPECT_EQ(to_vector(farthest_point_sampling(points, 4)), (std::vector<int64_t>{0, 3, 1, 2}));
}

TEST(FarthestPointSampling, LatticeTiesGoToTheSmallerIndexInEveryLane) {
    // A 5x5x5 integer lattice: exact squared distances with many ties, spread over the vector
    // lanes of the distance update and its scalar tail (125 is not a multiple of 8).
    at::Tensor axis = at::arange(5, at::kFloat);
    std::vector<at::Tensor> grid = at::meshgrid({axis, axis, axis}, "ij");
    at::Tensor points = at::stack({grid[0], grid[1], grid[2]}, -1).view({125, 3});
    for (int64_t start : {0, 62, 124})
        EXPECT_EQ(to_vector(farthest_point_sampling(points, 125, start)),
                  naive_fps<float>(points, 125, start));
}

TEST(FarthestPointSampling, AllPointsGivesAPermutationAndBadInputThrows) {
    at::Tensor points = uniform_random_points(300, 3);
    std::vector<int64_t> all = to_vector(farthest_point_sampling(points, 300, 7));
    EXPECT_EQ(all.front(), 7);
    EXPECT_EQ(std::set<int64_t>(all.begin(), all.end()).size(), 300u);
    EXPECT_EQ(farthest_point_sampling(points, 0).numel(), 0);
    EXPECT_THROW(farthest_point_sampling(points, 301), InputError);
    EXPECT_THROW(farthest_point_sampling(points, 5, 300), InputError);
    EXPECT_THROW(farthest_point_sampling(points, 5, -1), InputError);
    EXPECT_THROW(farthest_point_sampling(at::zeros({5, 2}), 1), InputError);
}

TEST(FarthestPointSampling, PrunedEqualsTheFullScanOnLargeClouds) {
    // Many leaves, every pick up to all points: uniform, on a thin curved sheet (a scan-like
    // surface), and clustered with a far outlier (boxes of very different sizes).
    at::Tensor uniform = uniform_random_points(30000, 11);
    at::Tensor sheet = uniform.clone();
    sheet.select(1, 2).copy_(at::sin(3 * sheet.select(1, 0)) * 0.2 + sheet.select(1, 2) * 1e-3);
    at::Tensor clustered =
        at::cat({uniform_random_points(20000, 12) * 0.01,
                 uniform_random_points(9999, 13) * 0.1 + 0.5, at::full({1, 3}, 40.f)});
    for (const at::Tensor& points : {uniform, sheet, clustered})
        for (int64_t m : {int64_t{1}, int64_t{7}, int64_t{4000}, int64_t{30000}})
            EXPECT_EQ(to_vector(farthest_point_sampling_pruned(points, m, 3)),
                      to_vector(farthest_point_sampling(points, m, 3)))
                << m << " points";
}

TEST(FarthestPointSampling, PrunedBreaksTiesAndRepeatsAsTheFullScan) {
    // A 20^3 lattice (exact distances, ties everywhere), and the same points twice (once every
    // distinct point is picked, only zero distances remain and indices repeat).
    at::Tensor axis = at::arange(20, at::kFloat);
    std::vector<at::Tensor> grid = at::meshgrid({axis, axis, axis}, "ij");
    at::Tensor lattice = at::stack({grid[0], grid[1], grid[2]}, -1).view({8000, 3});
    for (int64_t start : {0, 4321})
        EXPECT_EQ(to_vector(farthest_point_sampling_pruned(lattice, 8000, start)),
                  to_vector(farthest_point_sampling(lattice, 8000, start)));
    at::Tensor twice = at::cat({uniform_random_points(700, 14), uniform_random_points(700, 14)});
    EXPECT_EQ(to_vector(farthest_point_sampling_pruned(twice, 1400, 5)),
              to_vector(farthest_point_sampling(twice, 1400, 5)));
}

TEST(FarthestPointSampling, PrunedRejectsBadInput) {
    at::Tensor points = uniform_random_points(300, 3);
    EXPECT_EQ(farthest_point_sampling_pruned(points, 0).numel(), 0);
    EXPECT_THROW(farthest_point_sampling_pruned(points, 301), InputError);
    EXPECT_THROW(farthest_point_sampling_pruned(points, 5, 300), InputError);
    points[100][1] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(farthest_point_sampling_pruned(points, 5), InputError);
    points[100][1] = std::numeric_limits<float>::infinity();
    EXPECT_THROW(farthest_point_sampling_pruned(points, 5), InputError);
}

TEST(FarthestPointSampling, BatchedEqualsEachElement) {
    at::Tensor points = at::stack({uniform_random_points(500, 4), uniform_random_points(500, 5),
                                   uniform_random_points(500, 6)});
    at::Tensor batched = farthest_point_sampling_batched(points, 120);
    ASSERT_EQ(batched.sizes(), (at::IntArrayRef{3, 120}));
    for (int64_t b = 0; b < 3; ++b)
        EXPECT_EQ(to_vector(batched[b]), to_vector(farthest_point_sampling(points[b], 120)));
    EXPECT_EQ(farthest_point_sampling_batched(points, 0).sizes(), (at::IntArrayRef{3, 0}));
    EXPECT_THROW(farthest_point_sampling_batched(points, 501), InputError);
    EXPECT_THROW(farthest_point_sampling_batched(points[0], 5), InputError);
}

TEST(FarthestPointSampling, BatchedTensorPathEqualsTheTextbookAlgorithm) {
    // float64 input takes the tensor-op path (the one GPUs use).
    at::Tensor points =
        at::stack({uniform_random_points(400, 7), uniform_random_points(400, 8)}).to(at::kDouble);
    at::Tensor batched = farthest_point_sampling_batched(points, 60);
    for (int64_t b = 0; b < 2; ++b)
        EXPECT_EQ(to_vector(batched[b]), naive_fps<double>(points[b], 60, 0));
}

TEST(FarthestPointSampling, BatchedOnCudaEqualsTheCpu) {
    if (!at::hasCUDA()) GTEST_SKIP() << "no CUDA device";
    at::Tensor points = at::stack({uniform_random_points(700, 9), uniform_random_points(700, 10)});
    EXPECT_TRUE(at::equal(farthest_point_sampling_batched(points.cuda(), 90).cpu(),
                          farthest_point_sampling_batched(points, 90)));
}

TEST(RandomSubset, SortedDistinctInRangeAndSeeded) {
    at::Tensor subset = random_subset(1000, 100, 7);
    std::vector<int64_t> values = to_vector(subset);
    ASSERT_EQ(values.size(), 100u);
    EXPECT_TRUE(std::is_sorted(values.begin(), values.end()));
    EXPECT_EQ(std::set<int64_t>(values.begin(), values.end()).size(), 100u);
    EXPECT_GE(values.front(), 0);
    EXPECT_LT(values.back(), 1000);
    EXPECT_TRUE(at::equal(subset, random_subset(1000, 100, 7)));
    EXPECT_FALSE(at::equal(subset, random_subset(1000, 100, 8)));
    EXPECT_TRUE(at::equal(random_subset(50, 50, 1), at::arange(50)));
    EXPECT_EQ(random_subset(50, 0, 1).numel(), 0);
    EXPECT_THROW(random_subset(50, 51, 1), InputError);
}

TEST(RandomSubset, EveryIndexEquallyLikely) {
    // 20000 subsets of 5 out of 20: each index is expected 5000 times, sd 61.
    std::vector<int64_t> count(20, 0);
    for (uint64_t seed = 0; seed < 20000; ++seed)
        for (int64_t i : to_vector(random_subset(20, 5, seed))) ++count[i];
    for (int64_t c : count) EXPECT_NEAR(c, 5000, 300);
}

/// PU-GAN's sampler transcribed from its Python (with the std:: distributions standing in for
/// numpy's): loc = U(0.1, 0.9); a = int(normal(loc, 0.3) * n); keep a if in range and new.
std::vector<int64_t> pugan_nonuniform(int64_t n, int64_t m, uint64_t seed) {
    std::mt19937_64 rng(seed);
    const double loc = std::uniform_real_distribution<double>(0.1, 0.9)(rng);
    std::normal_distribution<double> normal(loc, 0.3);
    std::vector<int64_t> drawn;
    std::set<int64_t> seen;
    while (static_cast<int64_t>(drawn.size()) < m) {
        const double x = normal(rng) * n;
        const int64_t a = static_cast<int64_t>(std::trunc(x));  // Python int()
        if (x <= -1.0 || a < 0 || a >= n || seen.count(a)) continue;
        seen.insert(a);
        drawn.push_back(a);
    }
    return drawn;
}

TEST(NonuniformSubset, FollowsPuGansDrawsInOrder) {
    for (uint64_t seed : {1, 2, 3})
        EXPECT_EQ(to_vector(nonuniform_subset(1024, 256, seed)), pugan_nonuniform(1024, 256, seed));
    EXPECT_TRUE(at::equal(nonuniform_subset(500, 50, 9), nonuniform_subset(500, 50, 9)));
    EXPECT_FALSE(at::equal(nonuniform_subset(500, 50, 9), nonuniform_subset(500, 50, 10)));
    EXPECT_THROW(nonuniform_subset(10, 11, 1), InputError);
}

TEST(NonuniformSubset, AllIndicesTerminates) {
    std::vector<int64_t> all = to_vector(nonuniform_subset(2000, 2000, 4));
    EXPECT_EQ(std::set<int64_t>(all.begin(), all.end()).size(), 2000u);
    EXPECT_EQ(*std::min_element(all.begin(), all.end()), 0);
    EXPECT_EQ(*std::max_element(all.begin(), all.end()), 1999);
}

TEST(NonuniformSubset, ClustersAroundARandomLocation) {
    // The mean position of a uniform subset of 50 varies with sd 0.29/sqrt(50) = 0.04; the
    // non-uniform sampler's mean follows loc ~ U(0.1, 0.9) (shrunk to the centre by the
    // truncation at 0 and 1): its spread across seeds must be several times larger.
    auto spread_of_means = [](auto sampler) {
        std::vector<double> means;
        for (uint64_t seed = 0; seed < 400; ++seed) {
            at::Tensor subset = sampler(seed).to(at::kDouble) / 1000.0;
            means.push_back(subset.mean().item<double>());
        }
        return at::tensor(means).std().item<double>();
    };
    const double uniform = spread_of_means([](uint64_t s) { return random_subset(1000, 50, s); });
    const double clustered =
        spread_of_means([](uint64_t s) { return nonuniform_subset(1000, 50, s); });
    EXPECT_NEAR(uniform, 0.29 / std::sqrt(50.0), 0.01);
    EXPECT_GT(clustered, 3 * uniform);
}

/// Triangles of areas 1 and 3 in the planes z = 0 and z = 1.
TriangleMesh two_triangles() {
    return {at::tensor({0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 2.f, 0.f,  //
                        0.f, 0.f, 1.f, 3.f, 0.f, 1.f, 0.f, 2.f, 1.f})
                .view({6, 3}),
            at::tensor({0, 1, 2, 3, 4, 5}, at::kLong).view({2, 3})};
}

TEST(SampleUniform, CubeFixtureFacesOutward) {
    // Every face plane of the cube lies 0.5 from the centre along its outward normal.
    TriangleMesh cube = test::unit_cube();
    for (int64_t f = 0; f < 12; ++f)
        EXPECT_NEAR(test::dot(test::face_normal(cube, f), test::vertex(cube, f, 0)), 0.5, 1e-12)
            << "face " << f;
}

TEST(SampleUniform, PointsLieOnTheMeshWithTheirFaceNormal) {
    TriangleMesh cube = test::unit_cube();
    PointCloud cloud = sample_uniform(cube, 600, 11);
    ASSERT_EQ(cloud.points.sizes(), (at::IntArrayRef{600, 3}));
    ASSERT_TRUE(cloud.has_normals());
    auto p = cloud.points.accessor<float, 2>();
    auto n = cloud.normals.accessor<float, 2>();
    for (int64_t i = 0; i < 600; ++i) {
        auto [face, distance] = test::nearest_face(cube, {p[i][0], p[i][1], p[i][2]});
        EXPECT_LT(distance, 1e-5);
        const test::Vec3 normal = test::face_normal(cube, face);
        EXPECT_NEAR(test::dot(normal, {n[i][0], n[i][1], n[i][2]}), 1.0, 1e-6);
    }
}

TEST(SampleUniform, FaceChoiceIsAreaProportional) {
    // 40000 draws, small triangle's share 1/4: expected 10000, sd 87.
    PointCloud cloud = sample_uniform(two_triangles(), 40000, 12);
    const int64_t on_small = (cloud.points.select(1, 2) < 0.5).sum().item<int64_t>();
    EXPECT_NEAR(on_small, 10000, 450);
}

TEST(SampleUniform, UniformWithinATriangle) {
    // The corner triangle cut by the midpoints holds a quarter of the area, and the mean of
    // uniform samples is the centroid.
    TriangleMesh triangle{at::tensor({0.f, 0.f, 0.f, 2.f, 0.f, 0.f, 0.f, 1.f, 0.f}).view({3, 3}),
                          at::tensor({0, 1, 2}, at::kLong).view({1, 3})};
    at::Tensor points = sample_uniform(triangle, 40000, 13).points.to(at::kDouble);
    at::Tensor x = points.select(1, 0), y = points.select(1, 1);
    const double near_origin = ((x / 2 + y) < 0.5).to(at::kDouble).mean().item<double>();
    EXPECT_NEAR(near_origin, 0.25, 0.011);  // sd 0.0022
    EXPECT_NEAR(x.mean().item<double>(), 2.0 / 3, 0.01);
    EXPECT_NEAR(y.mean().item<double>(), 1.0 / 3, 0.005);
}

TEST(SampleUniform, DegenerateFacesAreNeverChosen) {
    // A zero-area face far away, between two good ones.
    TriangleMesh mesh{at::tensor({0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 9.f, 9.f, 9.f, 10.f,
                                  10.f, 10.f, 11.f, 11.f, 11.f})
                          .view({6, 3}),
                      at::tensor({0, 1, 2, 3, 4, 5, 0, 2, 1}, at::kLong).view({3, 3})};
    PointCloud cloud = sample_uniform(mesh, 5000, 14);
    EXPECT_LT(cloud.points.abs().max().item<float>(), 1.0f + 1e-6f);
    TriangleMesh flat{mesh.vertices, at::tensor({3, 4, 5}, at::kLong).view({1, 3})};
    EXPECT_THROW(sample_uniform(flat, 10, 1), InputError);
}

TEST(SampleUniform, SeededAndValidated) {
    TriangleMesh cube = test::unit_cube();
    EXPECT_TRUE(
        at::equal(sample_uniform(cube, 100, 5).points, sample_uniform(cube, 100, 5).points));
    EXPECT_FALSE(
        at::equal(sample_uniform(cube, 100, 5).points, sample_uniform(cube, 100, 6).points));
    EXPECT_EQ(sample_uniform(cube, 0, 5).size(), 0);
    EXPECT_THROW(sample_uniform(cube, -1, 5), InputError);
    TriangleMesh broken{cube.vertices, cube.faces + 8};
    EXPECT_THROW(sample_uniform(broken, 10, 5), InputError);
}

// Against a brute-force pairwise comparison: first occurrences only, in order, -0 equal to 0,
// and nothing that `exclude` holds.
TEST(DistinctPoints, KeepsFirstOccurrencesNotInExcludeAsBruteForce) {
    at::Tensor base = uniform_random_points(50, 31);
    at::Tensor points =
        at::cat({base.slice(0, 0, 5), base, base.slice(0, 10, 30)}).flip(0).contiguous();
    // One copy each of base[29] and base[28] become 0 and -0.
    points[0] = at::tensor({0.f, 0.f, 0.f});
    points[1] = at::tensor({-0.f, 0.f, -0.f});
    const at::Tensor exclude = base.slice(0, 40, 45);
    auto expected = [&](const at::Tensor& ex) {
        std::vector<int64_t> kept;
        for (int64_t i = 0; i < points.size(0); ++i) {
            bool seen = false;
            for (int64_t j = 0; j < i && !seen; ++j) seen = points[j].equal(points[i]);
            for (int64_t j = 0; ex.defined() && j < ex.size(0) && !seen; ++j)
                seen = ex[j].equal(points[i]);
            if (!seen) kept.push_back(i);
        }
        return kept;
    };
    auto as_vector = [](const at::Tensor& t) {
        return std::vector<int64_t>(t.data_ptr<int64_t>(), t.data_ptr<int64_t>() + t.numel());
    };
    // equal() compares values, so 0 and -0 are one point there too.
    EXPECT_EQ(as_vector(distinct_points(points)), expected({}));
    EXPECT_EQ(as_vector(distinct_points(points, exclude)), expected(exclude));
    EXPECT_EQ(count_distinct_points(points), 51);  // base and the zero
    EXPECT_EQ(distinct_points(at::empty({0, 3})).numel(), 0);
}

}  // namespace
}  // namespace pumeta
