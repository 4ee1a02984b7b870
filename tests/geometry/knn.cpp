#include "pumeta/geometry/knn.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <thread>
#include <utility>
#include <vector>

#include "pumeta/core/error.h"
#include "pumeta/geometry/sampling.h"
#include "support/test_util.h"

namespace pumeta {
namespace {

using Neighbour = std::pair<double, int64_t>;  // (squared distance, index)

/// Oracle: every point of `points` for each query, in double, sorted by (distance, index).
std::vector<std::vector<Neighbour>> all_neighbours(const at::Tensor& points,
                                                   const at::Tensor& queries) {
    auto p = points.accessor<float, 2>();
    auto q = queries.accessor<float, 2>();
    std::vector<std::vector<Neighbour>> result(queries.size(0));
    for (int64_t i = 0; i < queries.size(0); ++i) {
        for (int64_t j = 0; j < points.size(0); ++j) {
            double d = 0;
            for (int axis = 0; axis < 3; ++axis) {
                const double diff = double(q[i][axis]) - double(p[j][axis]);
                d += diff * diff;
            }
            result[i].emplace_back(d, j);
        }
        std::sort(result[i].begin(), result[i].end());
    }
    return result;
}

/// Tolerant of near-ties, which float32 may order differently from double: the reported
/// distances must be the oracle's k smallest, each reported distance must be the true distance
/// of the reported index, and indices must be distinct.
void expect_matches_oracle(const KnnResult& result, const at::Tensor& points,
                           const at::Tensor& queries, int64_t k) {
    ASSERT_EQ(result.indices.sizes(), (at::IntArrayRef{queries.size(0), k}));
    ASSERT_EQ(result.sq_distances.sizes(), (at::IntArrayRef{queries.size(0), k}));
    ASSERT_EQ(result.indices.scalar_type(), at::kLong);
    ASSERT_EQ(result.sq_distances.scalar_type(), at::kFloat);
    const auto oracle = all_neighbours(points, queries);
    auto index = result.indices.accessor<int64_t, 2>();
    auto sq_distance = result.sq_distances.accessor<float, 2>();
    int64_t exact_rows = 0;
    for (int64_t i = 0; i < queries.size(0); ++i) {
        std::vector<int64_t> found, expected;
        for (int64_t j = 0; j < k; ++j) {
            EXPECT_NEAR(sq_distance[i][j], oracle[i][j].first, 1e-6) << "query " << i;
            const int64_t n = index[i][j];
            ASSERT_TRUE(n >= 0 && n < points.size(0));
            auto true_distance = std::find_if(oracle[i].begin(), oracle[i].end(),
                                              [&](const Neighbour& e) { return e.second == n; });
            EXPECT_NEAR(sq_distance[i][j], true_distance->first, 1e-6);
            found.push_back(n);
            expected.push_back(oracle[i][j].second);
        }
        std::sort(found.begin(), found.end());
        std::sort(expected.begin(), expected.end());
        EXPECT_EQ(std::unique(found.begin(), found.end()), found.end());
        exact_rows += found == expected;
    }
    // Random points have near-ties only rarely: almost every neighbour set is exact.
    EXPECT_GE(exact_rows, queries.size(0) * 98 / 100);
}

/// Integer points of a shuffled n^3 grid: exact float distances with very many ties.
at::Tensor shuffled_grid(int64_t n, uint64_t seed) {
    std::vector<float> xyz;
    for (int64_t x = 0; x < n; ++x)
        for (int64_t y = 0; y < n; ++y)
            for (int64_t z = 0; z < n; ++z) xyz.insert(xyz.end(), {float(x), float(y), float(z)});
    at::Tensor grid = at::tensor(xyz).view({-1, 3});
    std::vector<int64_t> order(grid.size(0));
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), std::mt19937_64(seed));
    return grid.index_select(0, at::tensor(order));
}

TEST(KdTree, MatchesDoubleOracleOnRandomPoints) {
    at::Tensor points = uniform_random_points(2000, 1);
    at::Tensor queries = uniform_random_points(300, 2) * 1.2;
    KdTree tree(points);
    EXPECT_EQ(tree.size(), 2000);
    for (int64_t k : {1, 7, 16, 64})
        expect_matches_oracle(tree.query(queries, k), points, queries, k);
}

TEST(KdTree, BreaksTiesByIndex) {
    at::Tensor points = shuffled_grid(8, 3);
    // Grid points and cell centres: each has many neighbours at exactly equal distances.
    at::Tensor queries = at::cat({points.slice(0, 0, 100), points.slice(0, 100, 200) + 0.5});
    const auto oracle = all_neighbours(points, queries);
    for (int64_t k : {1, 5, 9, 27}) {
        KnnResult result = KdTree(points).query(queries, k);
        for (int64_t i = 0; i < queries.size(0); ++i)
            for (int64_t j = 0; j < k; ++j) {
                ASSERT_EQ(result.indices[i][j].item<int64_t>(), oracle[i][j].second)
                    << "k " << k << " query " << i << " rank " << j;
                ASSERT_EQ(result.sq_distances[i][j].item<float>(), oracle[i][j].first);
            }
    }
}

TEST(KdTree, FirstNeighbourOfEachPointIsItself) {
    at::Tensor points = uniform_random_points(1000, 4);
    KnnResult result = KdTree(points).query(points, 3);
    EXPECT_TRUE(at::equal(result.indices.select(1, 0), at::arange(1000)));
    EXPECT_TRUE(at::equal(result.sq_distances.select(1, 0), at::zeros({1000})));
    EXPECT_TRUE((result.sq_distances.select(1, 1) > 0).all().item<bool>());
}

TEST(KdTree, SameResultWithOneThreadAndFromConcurrentCallers) {
    at::Tensor points = uniform_random_points(5000, 5);
    at::Tensor queries = uniform_random_points(4000, 6);
    KdTree tree(points);
    KnnResult parallel = tree.query(queries, 8);
    const int threads = at::get_num_threads();
    at::set_num_threads(1);
    KnnResult serial = tree.query(queries, 8);
    at::set_num_threads(threads);
    EXPECT_TRUE(at::equal(parallel.indices, serial.indices));
    EXPECT_TRUE(at::equal(parallel.sq_distances, serial.sq_distances));

    std::vector<KnnResult> concurrent(3);
    std::vector<std::thread> callers;
    for (auto& result : concurrent)
        callers.emplace_back([&tree, &queries, &result] { result = tree.query(queries, 8); });
    for (auto& caller : callers) caller.join();
    for (const auto& result : concurrent) {
        EXPECT_TRUE(at::equal(result.indices, serial.indices));
        EXPECT_TRUE(at::equal(result.sq_distances, serial.sq_distances));
    }
}

TEST(KdTree, SurvivesMoveAndOwnsItsCopyOfThePoints) {
    at::Tensor points = uniform_random_points(300, 7);
    at::Tensor queries = uniform_random_points(50, 8);
    KdTree original(points);
    KnnResult before = original.query(queries, 4);
    points.zero_();
    KdTree moved(std::move(original));
    KdTree assigned(at::zeros({1, 3}));
    assigned = std::move(moved);
    KnnResult after = assigned.query(queries, 4);
    EXPECT_TRUE(at::equal(before.indices, after.indices));
    EXPECT_TRUE(at::equal(before.sq_distances, after.sq_distances));
}

TEST(KdTree, RejectsBadInput) {
    EXPECT_THROW(KdTree(at::zeros({0, 3})), InputError);
    EXPECT_THROW(KdTree(at::zeros({5, 2})), InputError);
    EXPECT_THROW(KdTree(at::zeros({5, 3}, at::kDouble)), InputError);
    KdTree tree(uniform_random_points(10, 9));
    EXPECT_THROW(tree.query(uniform_random_points(3, 1), 0), InputError);
    EXPECT_THROW(tree.query(uniform_random_points(3, 1), 11), InputError);
    EXPECT_THROW(tree.query(at::zeros({3, 4}), 1), InputError);
    KnnResult empty = tree.query(at::zeros({0, 3}), 2);
    EXPECT_EQ(empty.indices.sizes(), (at::IntArrayRef{0, 2}));
}

TEST(KnnBruteForce, MatchesDoubleOracle) {
    at::Tensor points = uniform_random_points(700, 10);
    at::Tensor queries = uniform_random_points(200, 11);
    for (int64_t k : {1, 16})
        expect_matches_oracle(knn_brute_force(points, queries, k), points, queries, k);
}

TEST(KnnBruteForce, AgreesWithKdTreeBitForBitIncludingTies) {
    for (const at::Tensor& points : {uniform_random_points(1500, 12), shuffled_grid(9, 13)}) {
        at::Tensor queries = at::cat({points.slice(0, 0, 300), points.slice(0, 300, 400) + 0.5});
        for (int64_t k : {1, 6, 27}) {
            KnnResult tree = KdTree(points).query(queries, k);
            KnnResult brute = knn_brute_force(points, queries, k);
            EXPECT_TRUE(at::equal(tree.indices, brute.indices)) << "k " << k;
            EXPECT_TRUE(at::equal(tree.sq_distances, brute.sq_distances)) << "k " << k;
        }
    }
}

TEST(KnnBruteForce, ChunkedQueriesGiveTheSameAnswer) {
    // 4096 x 3000 pairs exceed one block of the brute force: several chunks.
    at::Tensor points = uniform_random_points(4096, 14);
    at::Tensor queries = uniform_random_points(3000, 15);
    KnnResult brute = knn_brute_force(points, queries, 5);
    KnnResult tree = KdTree(points).query(queries, 5);
    EXPECT_TRUE(at::equal(tree.indices, brute.indices));
    EXPECT_TRUE(at::equal(tree.sq_distances, brute.sq_distances));
}

TEST(KnnIndices, AreKnnsIndicesForTrackedTensorsOfAnyFloatingType) {
    // A network's coordinates: double, requiring gradients, batched.
    const at::Tensor points =
        at::rand({2, 300, 3}, at::TensorOptions().dtype(at::kDouble)).requires_grad_(true);
    const at::Tensor queries = at::rand({2, 50, 3}, at::TensorOptions().dtype(at::kDouble));
    const at::Tensor idx = knn_indices(points, queries, 6);
    EXPECT_FALSE(idx.requires_grad());
    EXPECT_EQ(idx.scalar_type(), at::kLong);
    EXPECT_TRUE(idx.equal(
        knn(points.detach().to(at::kFloat).contiguous(), queries.to(at::kFloat).contiguous(), 6)
            .indices));
    // Unbatched too, and nearest first.
    const at::Tensor one = knn_indices(points[0], points[0], 2);
    EXPECT_TRUE(one.select(1, 0).equal(at::arange(300, at::kLong)));
    EXPECT_THROW(knn_indices(points, queries, 301), InputError);
}

TEST(KnnBruteForce, BatchedEqualsEachElementAlone) {
    at::Tensor points = at::stack({uniform_random_points(400, 16), uniform_random_points(400, 17),
                                   shuffled_grid(8, 18).slice(0, 0, 400)});
    at::Tensor queries = at::stack({uniform_random_points(90, 19), uniform_random_points(90, 20),
                                    shuffled_grid(8, 21).slice(0, 0, 90) + 0.5});
    KnnResult batched = knn_brute_force(points, queries, 9);
    ASSERT_EQ(batched.indices.sizes(), (at::IntArrayRef{3, 90, 9}));
    for (int64_t b = 0; b < 3; ++b) {
        KnnResult single = knn_brute_force(points[b], queries[b], 9);
        EXPECT_TRUE(at::equal(batched.indices[b], single.indices));
        EXPECT_TRUE(at::equal(batched.sq_distances[b], single.sq_distances));
    }
}

TEST(KnnBruteForce, RejectsBadInput) {
    at::Tensor points = uniform_random_points(10, 22);
    EXPECT_THROW(knn_brute_force(points, points, 11), InputError);
    EXPECT_THROW(knn_brute_force(points.unsqueeze(0), points, 2), InputError);
    EXPECT_THROW(knn_brute_force(points.unsqueeze(0).expand({2, 10, 3}),
                                 points.unsqueeze(0).expand({3, 10, 3}), 2),
                 InputError);
    EXPECT_THROW(knn_brute_force(points.unsqueeze(0).to(at::kDouble),
                                 points.unsqueeze(0).to(at::kDouble), 2),
                 InputError);
}

TEST(Knn, MatchesTheOracleFromOnePointToMany) {
    for (int64_t n : {1, 60, 3000}) {
        at::Tensor points = uniform_random_points(n, 23);
        at::Tensor queries = uniform_random_points(400, 24);
        const int64_t k = std::min<int64_t>(n, 4);
        expect_matches_oracle(knn(points, queries, k), points, queries, k);
    }
    at::Tensor small = uniform_random_points(60, 25);
    EXPECT_THROW(knn(small, small, 61), InputError);
    EXPECT_THROW(knn(small, small, 0), InputError);
}

TEST(Knn, BatchedOnCpuEqualsTheBruteForce) {
    at::Tensor points =
        at::stack({uniform_random_points(300, 26), shuffled_grid(7, 27).slice(0, 0, 300)});
    at::Tensor queries =
        at::stack({uniform_random_points(120, 28), shuffled_grid(5, 29).slice(0, 0, 120) + 0.5});
    KnnResult trees = knn(points, queries, 10);
    KnnResult brute = knn_brute_force(points, queries, 10);
    ASSERT_EQ(trees.indices.sizes(), (at::IntArrayRef{2, 120, 10}));
    EXPECT_TRUE(at::equal(trees.indices, brute.indices));
    EXPECT_TRUE(at::equal(trees.sq_distances, brute.sq_distances));
    EXPECT_THROW(knn(points, queries[0], 3), InputError);
}

TEST(Knn, WorksOnCudaWhenAvailable) {
    if (!at::hasCUDA()) GTEST_SKIP() << "no CUDA device";
    at::Tensor points = uniform_random_points(3000, 30);
    at::Tensor queries = uniform_random_points(500, 31);
    KnnResult cpu = knn_brute_force(points, queries, 8);
    KnnResult gpu = knn(points.cuda(), queries.cuda(), 8);
    EXPECT_TRUE(at::equal(cpu.indices, gpu.indices.cpu()));
    EXPECT_TRUE(at::allclose(cpu.sq_distances, gpu.sq_distances.cpu()));
}

}  // namespace
}  // namespace pumeta
