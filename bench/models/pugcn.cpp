// PU-GCN training-step cost at the paper's setting (batch 64 × 256 points, r = 4), whole and
// per component (the breakdown that guides optimisation). The argument is the thread count.
//
// glibc serves allocations above 32 MiB with mmap and returns them on free, so each of the
// step's ~42 MB per-edge tensors is page-faulted and zeroed by the kernel anew (3-8x slower
// steps). main() keeps freed memory in the heap instead, as pumeta's programs should.
#include "pumeta/models/pugcn.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>
#include <torch/csrc/autograd/autograd.h>

#include "pumeta/core/allocator.h"
#include "pumeta/nn/chamfer_loss.h"
#include "pumeta/nn/conv.h"
#include "pumeta/nn/dense_gcn.h"
#include "pumeta/nn/graph.h"

namespace {

using pumeta::ParamMap;

constexpr int64_t kBatch = 64, kPoints = 256, kRatio = 4;

at::Tensor uniform(std::vector<int64_t> shape, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    return at::rand(shape, gen);
}

std::vector<at::Tensor> values(const ParamMap& params) {
    std::vector<at::Tensor> out;
    for (const auto& [name, tensor] : params) out.push_back(tensor);
    return out;
}

const pumeta::PuGcn& model() {
    static pumeta::PuGcn instance(pumeta::PuGcnOptions::from_json({{"ratio", kRatio}}));
    return instance;
}

void patches_per_second(benchmark::State& state) {
    state.counters["patches/s"] =
        benchmark::Counter(double(kBatch), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_PuGcnForward(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    at::Tensor x = uniform({kBatch, kPoints, 3}, 1);
    at::NoGradGuard no_grad;
    for (auto _ : state) benchmark::DoNotOptimize(model().upsample(x));
    patches_per_second(state);
}

void BM_PuGcnTrainingStep(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    at::Tensor x = uniform({kBatch, kPoints, 3}, 1);
    at::Tensor y = uniform({kBatch, kPoints * kRatio, 3}, 2);
    for (auto _ : state) {
        at::Tensor loss = model().loss(x, y, model().parameters());
        benchmark::DoNotOptimize(torch::autograd::grad({loss}, values(model().parameters())));
    }
    patches_per_second(state);
}

// Components with forward + backward, at the shapes they have in the full step (per step:
// 1 xyz and 2 feature graphs, 4 DenseGCN paths, 1 NodeShuffle edge conv, 1 loss).

void BM_KnnGraphXyz(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    at::Tensor x = uniform({kBatch, kPoints, 3}, 3);
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::knn_graph(x, 20));
}

void BM_KnnGraphFeatures(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    at::Tensor f = uniform({kBatch, kPoints, 193}, 4);
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::knn_graph(f, 40));
}

void BM_DenseGcnPath(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    at::Tensor x = uniform({kBatch, kPoints, 32}, 5).requires_grad_(true);
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
    at::set_num_threads(int(state.range(0)));
    at::Tensor x = uniform({kBatch, kPoints, 64}, 6).requires_grad_(true);
    at::Tensor idx = pumeta::knn_graph(uniform({kBatch, kPoints, 3}, 7), 20);
    ParamMap params;
    std::mt19937_64 rng(0);
    pumeta::add_edge_conv(params, "e", 64, 64 * kRatio, rng);
    for (auto _ : state) {
        at::Tensor y = pumeta::edge_conv(x, idx, params, "e");
        benchmark::DoNotOptimize(torch::autograd::grad({y.sum()}, values(params)));
    }
}

void BM_ChamferLoss(benchmark::State& state) {
    at::set_num_threads(int(state.range(0)));
    at::Tensor pred = uniform({kBatch, kPoints * kRatio, 3}, 8).requires_grad_(true);
    at::Tensor target = uniform({kBatch, kPoints * kRatio, 3}, 9);
    for (auto _ : state)
        benchmark::DoNotOptimize(
            torch::autograd::grad({pumeta::chamfer_loss(pred, target)}, {pred}));
}

BENCHMARK(BM_PuGcnForward)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_PuGcnTrainingStep)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_KnnGraphXyz)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_KnnGraphFeatures)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DenseGcnPath)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_NodeShuffleEdgeConv)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ChamferLoss)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
    pumeta::keep_freed_memory();  // as the CLI
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
