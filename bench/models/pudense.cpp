// PU-Dense training-step and inference cost: a batch of 8 patches of 256 -> 2,048 points
// (r = 8) at the compact and the paper width. The argument is the thread count.
#include "pumeta/models/pudense.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

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

BENCHMARK_MAIN();
