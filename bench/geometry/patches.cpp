// Patch extraction of the upsampling pipeline on a 300k-point cloud: seeds by FPS per k-d tree
// part of at most 70,000 points (the default) against FPS over the whole cloud (the baseline,
// quadratic in the cloud size). scripts/bench.sh prints the ratio.
#include "pumeta/geometry/patches.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <limits>
#include <random>

namespace {

at::Tensor random_cloud(int64_t n, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> uniform(-1.f, 1.f);
    at::Tensor points = at::empty({n, 3}, at::kFloat);
    float* p = points.data_ptr<float>();
    for (int64_t i = 0; i < 3 * n; ++i) p[i] = uniform(rng);
    return points;
}

void extract(benchmark::State& state, int64_t part_points) {
    at::set_num_threads(1);
    static const at::Tensor cloud = random_cloud(300000, 1);
    pumeta::PatchOptions options;
    options.fps_part_points = part_points;
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::extract_patches(cloud, options).points);
}

void BM_ExtractPatchesPerPart(benchmark::State& state) { extract(state, 70000); }
void BM_ExtractPatchesWholeCloudFps(benchmark::State& state) {
    extract(state, std::numeric_limits<int64_t>::max());
}
BENCHMARK(BM_ExtractPatchesPerPart)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ExtractPatchesWholeCloudFps)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
