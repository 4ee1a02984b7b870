// Whole-cloud upsampling of large clouds (4x): the shipped PU-GCN against the midpoint
// baseline on the same cloud, so that every method a user can run is seen to scale like the
// network. Arguments: input points (100k and 1M). One iteration each (the network takes a
// minute and more on a million points); after the runs, the midpoint's time in units of the
// network's time on the same cloud (target: at most 2x on 1M points).
#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>

#include "pumeta/core/allocator.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/inference/model_file.h"
#include "pumeta/inference/upsample.h"

namespace {

using namespace pumeta;

const at::Tensor& cloud(int64_t n) {
    static std::map<int64_t, at::Tensor> clouds;
    auto& points = clouds[n];
    if (!points.defined()) points = sample_uniform(generate_shape(5), n, 1).points;
    return points;
}

std::map<std::pair<std::string, int64_t>, double> seconds;

void record(benchmark::State& state, const std::string& method, double elapsed) {
    seconds[{method, state.range(0)}] = elapsed;
    state.SetIterationTime(elapsed);
}

void BM_Network(benchmark::State& state) {
    const std::string path = (std::filesystem::path(models_dir()) / "pugcn-x4.pt").string();
    if (!std::filesystem::exists(path)) {
        state.SkipWithError("no shipped model (models/pugcn-x4.pt)");
        return;
    }
    const InferenceModel model = load_inference_model(path);
    const at::Tensor& points = cloud(state.range(0));
    for (auto _ : state) {
        auto start = std::chrono::steady_clock::now();
        UpsampleResult result = upsample_cloud(*model.backbone, points, UpsampleOptions());
        benchmark::DoNotOptimize(result.points.data_ptr<float>());
        record(state, "network",
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
}
BENCHMARK(BM_Network)
    ->Arg(100000)
    ->Arg(1000000)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kSecond);

void BM_Midpoint(benchmark::State& state) {
    const at::Tensor& points = cloud(state.range(0));
    for (auto _ : state) {
        auto start = std::chrono::steady_clock::now();
        at::Tensor out = midpoint_upsample(points, 4);
        benchmark::DoNotOptimize(out.data_ptr<float>());
        record(state, "midpoint",
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
}
BENCHMARK(BM_Midpoint)
    ->Arg(100000)
    ->Arg(1000000)
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kSecond);

}  // namespace

int main(int argc, char** argv) {
    pumeta::keep_freed_memory();  // as the CLI runs (core/allocator.h)
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    std::printf("midpoint time / network time, same cloud, %d threads (target: <= 2 at 1M):\n",
                at::get_num_threads());
    for (int64_t n : {100000, 1000000}) {
        auto network = seconds.find({"network", n}), midpoint = seconds.find({"midpoint", n});
        if (network == seconds.end() || midpoint == seconds.end()) continue;
        std::printf("  %8lld points: network %7.1f s, midpoint %7.1f s: %.2fx\n",
                    static_cast<long long>(n), network->second, midpoint->second,
                    midpoint->second / network->second);
    }
    return 0;
}
