// kNN on 100k random points, queries = the points, k = 16: pumeta's KdTree (parallel over
// queries) against nanoflann used directly on one thread; then small and batched searches,
// tree against brute force.
#include "pumeta/geometry/knn.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <algorithm>
#include <nanoflann.hpp>
#include <random>
#include <vector>

#include "pumeta/geometry/sampling.h"

namespace {

constexpr int64_t kPoints = 100000;
constexpr int64_t kNeighbours = 16;

using pumeta::uniform_random_points;

const at::Tensor& cloud() {
    static const at::Tensor points = uniform_random_points(kPoints, 1);
    return points;
}

/// The baseline: nanoflann's own adaptor and result set, single-threaded.
struct Buffer {
    const float* xyz;
    size_t count;
    size_t kdtree_get_point_count() const { return count; }
    float kdtree_get_pt(uint32_t i, size_t dim) const { return xyz[3 * i + dim]; }
    template <class BoundingBox>
    bool kdtree_get_bbox(BoundingBox&) const {
        return false;
    }
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Buffer>,
                                                 Buffer, 3, uint32_t>;

void nanoflann_query_all(const Tree& tree, const float* xyz, int64_t n,
                         std::vector<uint32_t>& indices, std::vector<float>& sq_distances) {
    for (int64_t q = 0; q < n; ++q) {
        nanoflann::KNNResultSet<float, uint32_t> result(kNeighbours);
        result.init(indices.data() + q * kNeighbours, sq_distances.data() + q * kNeighbours);
        tree.findNeighbors(result, xyz + 3 * q, nanoflann::SearchParams());
    }
}

/// state.range(0): ATen threads (1 = the same single thread as the nanoflann baseline).
void BM_KdTreeBuildAndQuery(benchmark::State& state) {
    at::set_num_threads(static_cast<int>(state.range(0)));
    for (auto _ : state) {
        pumeta::KdTree tree(cloud());
        benchmark::DoNotOptimize(tree.query(cloud(), kNeighbours));
    }
}
BENCHMARK(BM_KdTreeBuildAndQuery)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_KdTreeQuery(benchmark::State& state) {
    at::set_num_threads(static_cast<int>(state.range(0)));
    pumeta::KdTree tree(cloud());
    for (auto _ : state) benchmark::DoNotOptimize(tree.query(cloud(), kNeighbours));
}
BENCHMARK(BM_KdTreeQuery)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_NanoflannBuildAndQuery(benchmark::State& state) {
    const Buffer buffer{cloud().data_ptr<float>(), kPoints};
    std::vector<uint32_t> indices(kPoints * kNeighbours);
    std::vector<float> sq_distances(kPoints * kNeighbours);
    for (auto _ : state) {
        Tree tree(3, buffer, nanoflann::KDTreeSingleIndexAdaptorParams(10));
        nanoflann_query_all(tree, buffer.xyz, kPoints, indices, sq_distances);
        benchmark::DoNotOptimize(indices.data());
    }
}
BENCHMARK(BM_NanoflannBuildAndQuery)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_NanoflannQuery(benchmark::State& state) {
    const Buffer buffer{cloud().data_ptr<float>(), kPoints};
    Tree tree(3, buffer, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    std::vector<uint32_t> indices(kPoints * kNeighbours);
    std::vector<float> sq_distances(kPoints * kNeighbours);
    for (auto _ : state) {
        nanoflann_query_all(tree, buffer.xyz, kPoints, indices, sq_distances);
        benchmark::DoNotOptimize(indices.data());
    }
}
BENCHMARK(BM_NanoflannQuery)->Unit(benchmark::kMillisecond)->UseRealTime();

/// Why knn() uses the tree for every CPU size: N = Q = state.range(0), k = min(16, N), one
/// thread.
void BM_SmallBruteForce(benchmark::State& state) {
    at::set_num_threads(1);
    at::Tensor points = uniform_random_points(state.range(0), 2);
    const int64_t k = std::min<int64_t>(16, state.range(0));
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::knn_brute_force(points, points, k));
}
BENCHMARK(BM_SmallBruteForce)->RangeMultiplier(4)->Range(16, 4096)->UseRealTime();

void BM_SmallKdTree(benchmark::State& state) {
    at::set_num_threads(1);
    at::Tensor points = uniform_random_points(state.range(0), 2);
    const int64_t k = std::min<int64_t>(16, state.range(0));
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::KdTree(points).query(points, k));
}
BENCHMARK(BM_SmallKdTree)->RangeMultiplier(4)->Range(16, 4096)->UseRealTime();

/// Batches as the networks query them, [B,N,3] with queries = points, k = 16, two threads:
/// knn() (a tree per element) against the brute force. Args: B, N.
void BM_BatchedKnn(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor points = uniform_random_points(state.range(0) * state.range(1), 3)
                            .view({state.range(0), state.range(1), 3});
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::knn(points, points, 16));
}
BENCHMARK(BM_BatchedKnn)
    ->Args({64, 256})
    ->Args({8, 1024})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_BatchedBruteForce(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor points = uniform_random_points(state.range(0) * state.range(1), 3)
                            .view({state.range(0), state.range(1), 3});
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::knn_brute_force(points, points, 16));
}
BENCHMARK(BM_BatchedBruteForce)
    ->Args({64, 256})
    ->Args({8, 1024})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
