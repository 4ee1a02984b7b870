// PU-GCN training-step cost at the paper's setting (batch 64 × 256 points, r = 4) on 2 threads,
// whole and per component (the breakdown that guides optimisation).
#include "pumeta/models/pugcn.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>
#include <torch/csrc/autograd/autograd.h>

#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/dense_gcn.h"
#include "pumeta/nn/graph.h"

namespace {

using pumeta::ParamMap;

constexpr int64_t kBatch = 64, kPoints = 256, kRatio = 4;

at::Tensor patches(int64_t batch, int64_t n, int64_t channels, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    return at::rand({batch, n, channels}, gen);
}

std::vector<at::Tensor> values(const ParamMap& params) {
    std::vector<at::Tensor> out;
    for (const auto& [name, tensor] : params) out.push_back(tensor);
    return out;
}

void report(benchmark::State& state, int64_t patches_per_iteration) {
    state.counters["patches/s"] = benchmark::Counter(double(patches_per_iteration),
                                                     benchmark::Counter::kIsIterationInvariantRate);
}

const pumeta::PuGcn& model() {
    static pumeta::PuGcn instance(pumeta::PuGcnOptions::from_json({{"ratio", kRatio}}));
    return instance;
}

void BM_PuGcnForward(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor x = patches(kBatch, kPoints, 3, 1);
    at::NoGradGuard no_grad;
    for (auto _ : state) benchmark::DoNotOptimize(model().upsample(x));
    report(state, kBatch);
}

void BM_PuGcnForwardBackward(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor x = patches(kBatch, kPoints, 3, 1);
    at::Tensor y = patches(kBatch, kPoints * kRatio, 3, 2);
    for (auto _ : state) {
        at::Tensor loss = model().loss(x, y, model().parameters());
        benchmark::DoNotOptimize(torch::autograd::grad({loss}, values(model().parameters())));
    }
    report(state, kBatch);
}

// Components, each forward + backward, at the shapes of the full model.

void BM_KnnGraphFeatures193(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor f = patches(kBatch, kPoints, 193, 3);
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::knn_graph(f, 40));
}

void BM_DenseGcnPath(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor x = patches(kBatch, kPoints, 32, 4).requires_grad_(true);
    at::Tensor idx = pumeta::knn_graph(x, 20);
    ParamMap params;
    std::mt19937_64 rng(0);
    pumeta::add_dense_gcn(params, "p", 32, 32, rng);
    for (auto _ : state) {
        at::Tensor y = pumeta::dense_gcn(x, idx, params, "p");
        benchmark::DoNotOptimize(torch::autograd::grad({y.sum()}, values(params)));
    }
}

void BM_NodeShuffleEdgeConv(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor x = patches(kBatch, kPoints, 64, 5).requires_grad_(true);
    at::Tensor idx = pumeta::knn_graph(patches(kBatch, kPoints, 3, 6), 20);
    ParamMap params;
    std::mt19937_64 rng(0);
    pumeta::add_edge_conv(params, "e", 64, 64 * kRatio, rng);
    for (auto _ : state) {
        at::Tensor y = pumeta::edge_conv(x, idx, params, "e");
        benchmark::DoNotOptimize(torch::autograd::grad({y.sum()}, values(params)));
    }
}

void BM_ChamferLoss(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor pred = patches(kBatch, kPoints * kRatio, 3, 7).requires_grad_(true);
    at::Tensor target = patches(kBatch, kPoints * kRatio, 3, 8);
    for (auto _ : state)
        benchmark::DoNotOptimize(
            torch::autograd::grad({pumeta::chamfer_loss(pred, target)}, {pred}));
}

BENCHMARK(BM_PuGcnForward)->Unit(benchmark::kMillisecond)->MinTime(3);
BENCHMARK(BM_PuGcnForwardBackward)->Unit(benchmark::kMillisecond)->MinTime(5);
BENCHMARK(BM_KnnGraphFeatures193)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DenseGcnPath)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NodeShuffleEdgeConv)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ChamferLoss)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
