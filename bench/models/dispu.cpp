// Dis-PU step cost at the paper's training setting (batch 28 × 256 points, r = 4) on 2
// threads, at the paper's width and the compact preset; the extra cost of update_buffers in
// pretraining; and the memory of 16× (r = 16, N = 256), where the non-local attention holds
// (rN)² = 16.7 M scores per patch.
//
// peak_rss_MB is the process's peak resident set, so memory numbers are only meaningful for a
// benchmark run alone, e.g. --benchmark_filter='BM_DisPu16x/0/1$'.
#include "pumeta/models/dispu.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <map>

#include "pumeta/core/allocator.h"
#include "pumeta/nn/attention.h"
#include "pumeta/nn/gradients.h"

namespace {

using pumeta::DisPu;
using pumeta::DisPuOptions;

constexpr int64_t kBatch = 28, kPoints = 256, kRatio = 4;

at::Tensor patches(int64_t batch, int64_t n, int64_t channels, uint64_t seed) {
    at::Generator gen = at::detail::createCPUGenerator(seed);
    return at::rand({batch, n, channels}, gen);
}

const char* preset_name(int64_t preset) { return preset == 0 ? "paper" : "compact"; }

DisPu& model(int64_t preset, int64_t ratio) {
    static std::map<std::pair<int64_t, int64_t>, std::unique_ptr<DisPu>> models;
    auto& slot = models[{preset, ratio}];
    if (!slot)
        slot = std::make_unique<DisPu>(
            DisPuOptions::from_json({{"preset", preset_name(preset)}, {"ratio", ratio}}));
    return *slot;
}

void report(benchmark::State& state, int64_t patches_per_iteration) {
    state.counters["patches/s"] = benchmark::Counter(double(patches_per_iteration),
                                                     benchmark::Counter::kIsIterationInvariantRate);
    state.counters["peak_rss_MB"] = pumeta::peak_resident_mib();
}

// Arg: 0 = paper width, 1 = compact.
void BM_DisPuForward(benchmark::State& state) {
    at::set_num_threads(2);
    DisPu& m = model(state.range(0), kRatio);
    at::Tensor x = patches(kBatch, kPoints, 3, 1);
    at::NoGradGuard no_grad;
    for (auto _ : state) benchmark::DoNotOptimize(m.upsample(x));
    report(state, kBatch);
}

void BM_DisPuForwardBackward(benchmark::State& state) {
    at::set_num_threads(2);
    DisPu& m = model(state.range(0), kRatio);
    at::Tensor x = patches(kBatch, kPoints, 3, 1);
    at::Tensor y = patches(kBatch, kPoints * kRatio, 3, 2);
    for (auto _ : state) {
        at::Tensor loss = m.loss(x, y, m.parameters());
        benchmark::DoNotOptimize(pumeta::gradients(loss, m.parameters()));
    }
    report(state, kBatch);
}

// What pretraining adds per step: the generator again, without gradients.
void BM_DisPuUpdateBuffers(benchmark::State& state) {
    at::set_num_threads(2);
    DisPu& m = model(state.range(0), kRatio);
    at::Tensor x = patches(kBatch, kPoints, 3, 1);
    for (auto _ : state) m.update_buffers(x, m.parameters());
    report(state, kBatch);
}

// 16× at the paper's width. Args: batch, with gradients (0/1).
void BM_DisPu16x(benchmark::State& state) {
    at::set_num_threads(2);
    DisPu& m = model(0, 16);
    const int64_t batch = state.range(0);
    at::Tensor x = patches(batch, kPoints, 3, 3);
    at::Tensor y = patches(batch, kPoints * 16, 3, 4);
    for (auto _ : state) {
        if (state.range(1) == 0) {
            at::NoGradGuard no_grad;
            benchmark::DoNotOptimize(m.upsample(x));
        } else {
            at::Tensor loss = m.loss(x, y, m.parameters());
            benchmark::DoNotOptimize(pumeta::gradients(loss, m.parameters()));
        }
    }
    report(state, batch);
}

// The non-local branch alone at 16× (rN = 4096, bottleneck 64) for batch 8, without
// gradients, in blocks of 2^24 scores (Dis-PU's setting) or unblocked (2^40).
void BM_Attention16x(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor q = patches(8, 4096, 64, 5), k = patches(8, 4096, 64, 6);
    at::Tensor v = patches(8, 4096, 64, 7);
    at::NoGradGuard no_grad;
    for (auto _ : state)
        benchmark::DoNotOptimize(pumeta::blocked_attention(q, k, v, 0.125, state.range(0)));
    report(state, 8);
}

// CPU time is the whole process's (both threads): on a shared machine it estimates the cost
// better than wall time; on an idle one wall ≈ CPU / 2.
BENCHMARK(BM_DisPuForward)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->MinTime(3)
    ->MeasureProcessCPUTime();
BENCHMARK(BM_DisPuForwardBackward)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->MinTime(5)
    ->MeasureProcessCPUTime();
BENCHMARK(BM_DisPuUpdateBuffers)
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();
BENCHMARK(BM_DisPu16x)
    ->Args({1, 0})
    ->Args({1, 1})
    ->Args({8, 0})
    ->Args({8, 1})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();
BENCHMARK(BM_Attention16x)
    ->Arg(int64_t(1) << 24)
    ->Arg(int64_t(1) << 40)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
