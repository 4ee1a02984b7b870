// Whole-cloud upsampling of a 2,048-point object with the shipped models (models/, or
// $PUMETA_MODELS).
// - Before the benchmarks: the cost of test-time adaptation with N = 5 ("ours": the meta model
//   with its own step sizes) in units of the plain model's time on the same object, for every
//   shipped <backbone>-x<r>.pt / -meta.pt pair, one thread, plain and adapted runs alternating
//   so that a changing load on the machine affects both alike. The target is at most 3x.
// - Benchmarks: PU-GCN 4x plain and with N = 1, 5 (patches/s), and the midpoint baseline. The
//   argument is the thread count.
#include "pumeta/inference/upsample.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "pumeta/core/allocator.h"
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
    std::string path =
        (std::filesystem::path(models_dir()) / (meta ? "pugcn-x4-meta.pt" : "pugcn-x4.pt"))
            .string();
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
    AdaptationOverrides overrides;
    overrides.steps = tta_steps;
    if (!used->meta_trained) overrides.step_size = 0.03;
    options.adaptation = adaptation_for(used->adaptation, used->meta_trained, overrides);
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

/// Seconds of one whole-cloud upsampling.
double seconds_to_upsample(const InferenceModel& model, const UpsampleOptions& options) {
    auto start = std::chrono::steady_clock::now();
    UpsampleResult result = upsample_cloud(*model.backbone, input_cloud(), options);
    benchmark::DoNotOptimize(result.points.data_ptr<float>());
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// Plain vs N = 5 "ours" for each shipped pair, `rounds` alternating runs of each after a
/// warm-up of both.
void print_adaptation_cost(int rounds) {
    at::set_num_threads(1);
    std::printf("test-time adaptation cost, N = 5, 1 thread, 2,048-point object, %d rounds:\n",
                rounds);
    for (const char* name : {"pugcn-x4", "pugcn-x8", "dispu-x4", "dispu-x8", "pudense-x8"}) {
        std::string plain_path =
            (std::filesystem::path(models_dir()) / (std::string(name) + ".pt")).string();
        std::string meta_path =
            (std::filesystem::path(models_dir()) / (std::string(name) + "-meta.pt")).string();
        if (!std::filesystem::exists(plain_path) || !std::filesystem::exists(meta_path)) continue;
        InferenceModel plain = load_inference_model(plain_path);
        InferenceModel meta = load_inference_model(meta_path);
        UpsampleOptions plain_options, ours_options;
        AdaptationOverrides five;
        five.steps = 5;
        ours_options.adaptation = adaptation_for(meta.adaptation, meta.meta_trained, five);
        seconds_to_upsample(plain, plain_options);
        seconds_to_upsample(meta, ours_options);
        double plain_seconds = 0, ours_seconds = 0;
        for (int i = 0; i < rounds; ++i) {
            plain_seconds += seconds_to_upsample(plain, plain_options);
            ours_seconds += seconds_to_upsample(meta, ours_options);
        }
        std::printf("  %-10s plain %8.0f ms, ours %8.0f ms: %.2fx\n", name,
                    1e3 * plain_seconds / rounds, 1e3 * ours_seconds / rounds,
                    ours_seconds / plain_seconds);
    }
}

}  // namespace

int main(int argc, char** argv) {
    pumeta::keep_freed_memory();  // as the CLI runs (core/allocator.h)
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    print_adaptation_cost(3);
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
