// Chamfer distance between two 8,192-point clouds: pumeta's chamfer_distance against
// nanoflann used directly (two single-threaded trees, one nearest neighbour per point), the
// baseline measured in the same run. Run with --benchmark_repetitions=5 for medians.
#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <cmath>
#include <nanoflann.hpp>
#include <random>
#include <vector>

#include "pumeta/geometry/sampling.h"
#include "pumeta/metrics/metrics.h"

namespace {

constexpr int64_t kPoints = 8192;

/// uniform_random_points as a flat xyz vector, the layout of the nanoflann baseline.
std::vector<float> random_cloud(int64_t n, uint64_t seed) {
    at::Tensor points = pumeta::uniform_random_points(n, seed);
    return std::vector<float>(points.data_ptr<float>(), points.data_ptr<float>() + 3 * n);
}

at::Tensor to_tensor(const std::vector<float>& xyz) {
    return at::tensor(xyz, at::kFloat).view({-1, 3}).clone();
}

struct Cloud {
    const std::vector<float>& xyz;

    size_t kdtree_get_point_count() const { return xyz.size() / 3; }
    float kdtree_get_pt(size_t index, size_t dim) const { return xyz[3 * index + dim]; }
    template <class BoundingBox>
    bool kdtree_get_bbox(BoundingBox&) const {
        return false;
    }
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>, Cloud,
                                                 3, uint32_t>;

/// Mean squared distance from each point of `from` to its nearest point of `to`.
double mean_nearest_sq_distance(const std::vector<float>& from, const std::vector<float>& to) {
    Cloud cloud{to};
    Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    double sum = 0;
    for (size_t i = 0; i < from.size(); i += 3) {
        uint32_t index;
        float sq_distance;
        nanoflann::KNNResultSet<float, uint32_t> result(1);
        result.init(&index, &sq_distance);
        tree.findNeighbors(result, &from[i], nanoflann::SearchParams());
        sum += sq_distance;
    }
    return sum / (from.size() / 3);
}

double nanoflann_chamfer(const std::vector<float>& a, const std::vector<float>& b) {
    return mean_nearest_sq_distance(a, b) + mean_nearest_sq_distance(b, a);
}

void BM_ChamferPumeta(benchmark::State& state) {
    at::set_num_threads(static_cast<int>(state.range(0)));
    std::vector<float> pred = random_cloud(kPoints, 1), gt = random_cloud(kPoints, 2);
    at::Tensor pred_tensor = to_tensor(pred), gt_tensor = to_tensor(gt);
    double baseline = nanoflann_chamfer(pred, gt);
    double cd = pumeta::chamfer_distance(pred_tensor, gt_tensor);
    // Same neighbours up to float ties: the two must agree to float precision.
    if (std::abs(cd - baseline) > 1e-6 * baseline) state.SkipWithError("results differ");
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::chamfer_distance(pred_tensor, gt_tensor));
}
BENCHMARK(BM_ChamferPumeta)->ArgName("threads")->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_ChamferNanoflann(benchmark::State& state) {
    std::vector<float> pred = random_cloud(kPoints, 1), gt = random_cloud(kPoints, 2);
    for (auto _ : state) benchmark::DoNotOptimize(nanoflann_chamfer(pred, gt));
}
BENCHMARK(BM_ChamferNanoflann)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
