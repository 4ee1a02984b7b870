#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>
namespace {
constexpr int64_t K = 26, P = 10000;
void BM_Bmm(benchmark::State& s) { at::set_num_threads(2); int64_t C = s.range(0), D = s.range(1); at::Tensor g = at::randn({K, P, C}), w = at::randn({K, C, D});
  for (auto _ : s) benchmark::DoNotOptimize(at::bmm(g, w)); }
void BM_LoopMm(benchmark::State& s) { at::set_num_threads(2); int64_t C = s.range(0), D = s.range(1); at::Tensor g = at::randn({K, P, C}), w = at::randn({K, C, D});
  for (auto _ : s) for (int64_t k = 0; k < K; ++k) benchmark::DoNotOptimize(g[k].mm(w[k])); }
void BM_Bmm64(benchmark::State& s) { at::set_num_threads(2); int64_t C = s.range(0), D = s.range(1); at::Tensor g = at::randn({K, P, C}, at::kDouble), w = at::randn({K, C, D}, at::kDouble);
  for (auto _ : s) benchmark::DoNotOptimize(at::bmm(g, w)); }
void BM_Flat(benchmark::State& s) { at::set_num_threads(2); int64_t C = s.range(0), D = s.range(1); at::Tensor g = at::randn({P, K * C}), w = at::randn({K * C, D});
  for (auto _ : s) benchmark::DoNotOptimize(g.mm(w)); }
BENCHMARK(BM_Bmm)->Args({4, 4})->Args({16, 4})->Args({4, 8})->Args({16, 16})->Args({64,64})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_LoopMm)->Args({4, 4})->Args({16, 4})->Args({4, 8})->Args({16, 16})->Args({64,64})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Bmm64)->Args({4, 4})->Args({16, 16})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Flat)->Args({4, 4})->Args({16, 16})->Unit(benchmark::kMillisecond);
}
BENCHMARK_MAIN();
