// Whole-cloud upsampling 2,048 -> 8,192 points with the shipped PU-GCN (models/pugcn-x4.pt,
// or $PUMETA_MODELS): plain, with test-time adaptation (N = 1, 5 steps, the step sizes of
// the meta-trained model when models/pugcn-x4-meta.pt exists), and the midpoint baseline.
// The argument is the thread count. Counters: patches/s (plain) and the adaptation cost in
// units of the plain time measured in the same run (scripts/bench-upsample.sh prints both).
#include "pumeta/inference/upsample.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <filesystem>

#include "pumeta/data/shapes.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/inference/model_file.h"

namespace {

using namespace pumeta;

const at::Tensor& input_cloud() {
    // A procedural CAD-like object, blue-noise sampled like the test inputs.
    static const at::Tensor points = sample_poisson_disk(generate_shape(5), 2048, 1).points;
    return points;
}

const InferenceModel* model(bool meta) {
    static std::map<bool, std::unique_ptr<InferenceModel>> models;
    auto found = models.find(meta);
    if (found != models.end()) return found->second.get();
    std::string path = default_model_path(meta ? "pugcn-x4-meta.pt" : "pugcn-x4.pt");
    std::unique_ptr<InferenceModel> loaded;
    if (std::filesystem::exists(path))
        loaded = std::make_unique<InferenceModel>(load_inference_model(path));
    return (models[meta] = std::move(loaded)).get();
}

void BM_Upsample(benchmark::State& state, int64_t tta_steps) {
    at::set_num_threads(static_cast<int>(state.range(0)));
    const InferenceModel* plain = model(false);
    const InferenceModel* meta = model(true);
    const InferenceModel* used = tta_steps > 0 && meta ? meta : plain;
    if (!used) {
        state.SkipWithError("no shipped model (models/pugcn-x4.pt)");
        return;
    }
    UpsampleOptions options;
    options.tta_steps = tta_steps;
    set_adaptation(options, *used, used->meta_trained ? -1 : 0.03);
    int64_t patches = 0;
    for (auto _ : state) {
        UpsampleResult result = upsample_cloud(*used->backbone, input_cloud(), options);
        patches += result.patches;
        benchmark::DoNotOptimize(result.points.data_ptr<float>());
    }
    state.counters["patches_per_s"] =
        benchmark::Counter(static_cast<double>(patches), benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_Upsample, plain, 0)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_Upsample, tta1, 1)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_Upsample, tta5, 5)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_Midpoint(benchmark::State& state) {
    at::set_num_threads(static_cast<int>(state.range(0)));
    for (auto _ : state)
        benchmark::DoNotOptimize(midpoint_upsample(input_cloud(), 4).data_ptr<float>());
}
BENCHMARK(BM_Midpoint)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
