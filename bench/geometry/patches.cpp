// Patch extraction of the upsampling pipeline on a 300k-point cloud: seeds by FPS per k-d tree
// part of at most 70,000 points (the default) against FPS over the whole cloud (the baseline,
// quadratic in the cloud size). scripts/bench.sh prints the ratio.
#include "pumeta/geometry/patches.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <limits>
#include <random>

#include "pumeta/geometry/sampling.h"

namespace {

using pumeta::uniform_random_points;

void extract(benchmark::State& state, int64_t part_points) {
    at::set_num_threads(1);
    static const at::Tensor cloud = uniform_random_points(300000, 1);
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
