// PU-Dense training-step and inference cost: a batch of 8 patches of 256 -> 2,048 points
// (r = 8) at the compact and the paper width. The argument is the thread count. Before the
// benchmarks, a training step is timed with glibc's default allocator and again with
// keep_freed_memory() (what the CLI runs with), and the ratio printed.
#include "pumeta/models/pudense.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>

#include "pumeta/core/allocator.h"
#include "pumeta/nn/gradients.h"

namespace {

using pumeta::PuDense;
using pumeta::PuDenseOptions;

constexpr int64_t kBatch = 8, kPoints = 256, kRatio = 8;

/// Curved sheets in the unit disc, like normalised surface patches: [B, n, 3].
at::Tensor patches(int64_t n, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    at::Tensor r = at::sqrt(at::rand({kBatch, n}, gen)), a = at::rand({kBatch, n}, gen) * 6.2832;
    at::Tensor u = r * at::cos(a), v = r * at::sin(a);
    return at::stack({u, v, 0.3 * at::sin(2 * u) * at::cos(v)}, -1);
}

const PuDense& model(const std::string& preset) {
    static PuDense compact(PuDenseOptions::from_json({{"preset", "compact"}, {"ratio", kRatio}}));
    static PuDense paper(PuDenseOptions::from_json({{"preset", "paper"}, {"ratio", kRatio}}));
    return preset == "compact" ? compact : paper;
}

void report(benchmark::State& state) {
    state.counters["patches/s"] =
        benchmark::Counter(double(kBatch), benchmark::Counter::kIsIterationInvariantRate);
}

void loss_and_gradients(benchmark::State& state, const std::string& preset) {
    at::set_num_threads(int(state.range(0)));
    const PuDense& m = model(preset);
    at::Tensor gt = patches(kPoints * kRatio, 1);
    at::Tensor input = gt.narrow(1, 0, kPoints);  // the points are i.i.d.: a random subset
    for (auto _ : state)
        benchmark::DoNotOptimize(
            pumeta::gradients(m.loss(input, gt, m.parameters()), m.parameters()));
    report(state);
}

void upsample(benchmark::State& state, const std::string& preset) {
    at::set_num_threads(int(state.range(0)));
    const PuDense& m = model(preset);
    at::Tensor input = patches(kPoints, 2);
    for (auto _ : state) benchmark::DoNotOptimize(m.upsample(input));
    report(state);
}

BENCHMARK_CAPTURE(loss_and_gradients, compact, std::string("compact"))
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(loss_and_gradients, paper, std::string("paper"))
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(upsample, compact, std::string("compact"))
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

/// Mean seconds of `steps` compact training steps on one thread (after one warm-up step).
double seconds_per_step(int steps) {
    at::set_num_threads(1);
    const PuDense& m = model("compact");
    at::Tensor gt = patches(kPoints * kRatio, 1), input = gt.narrow(1, 0, kPoints);
    auto step = [&] { pumeta::gradients(m.loss(input, gt, m.parameters()), m.parameters()); };
    step();
    auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < steps; ++i) step();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / steps;
}

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    const double glibc_default = seconds_per_step(4);
    pumeta::keep_freed_memory();
    const double kept = seconds_per_step(4);
    std::printf(
        "compact training step, 1 thread: %.0f ms with glibc's default allocator, %.0f ms "
        "with keep_freed_memory(): %.2fx\n",
        1e3 * glibc_default, 1e3 * kept, glibc_default / kept);
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
