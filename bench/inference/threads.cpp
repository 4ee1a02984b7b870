// What a second thread gains in whole-cloud upsampling at 4×: patches go through the network
// in batches of a fixed composition that run concurrently, each on one thread
// (inference/upsample.cpp), so the output has the same bits at any thread count.
// - Before the benchmarks: for PU-GCN, Dis-PU (models/) and Grad-PU (the released weights
//   imported into data/imported/gradpu-pugan.pt, or $PUMETA_GRADPU), on a 2,048- and a
//   200,000-point cloud, the seconds at 1 and at 2 threads (runs alternating, so that a
//   changing load affects both alike) and their ratio, the speed-up; and whether the two
//   outputs have the same bits. The target on a 2-core machine is at least 1.8×.
// - Benchmarks: PU-GCN on the 2,048-point cloud; the argument is the thread count.
#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "pumeta/core/allocator.h"
#include "pumeta/data/shapes.h"
#include "pumeta/geometry/sampling.h"
#include "pumeta/inference/model_file.h"
#include "pumeta/inference/upsample.h"

namespace {

using namespace pumeta;
namespace fs = std::filesystem;

const at::Tensor& cloud(int64_t n) {
    static std::map<int64_t, at::Tensor> clouds;
    at::Tensor& points = clouds[n];
    // Blue noise like the test inputs; a large scan-like cloud uniformly (faster to draw).
    if (!points.defined())
        points = n <= 8192 ? sample_poisson_disk(generate_shape(5), n, 1).points
                           : sample_uniform(generate_shape(5), n, 1).points;
    return points;
}

/// The model files of the speed-up table that exist here, by label.
std::vector<std::pair<std::string, std::string>> model_files() {
    const char* gradpu = std::getenv("PUMETA_GRADPU");
    std::vector<std::pair<std::string, std::string>> files = {
        {"PU-GCN", (fs::path(models_dir()) / "pugcn-x4.pt").string()},
        {"Dis-PU", (fs::path(models_dir()) / "dispu-x4.pt").string()},
        {"Grad-PU", gradpu ? std::string(gradpu)
                           : std::string(PUMETA_SOURCE_DIR) + "/data/imported/gradpu-pugan.pt"}};
    std::vector<std::pair<std::string, std::string>> found;
    for (const auto& [label, file] : files)
        if (fs::exists(file))
            found.emplace_back(label, file);
        else
            std::printf("  (%s: no %s)\n", label.c_str(), file.c_str());
    return found;
}

/// One upsampling at `threads`: its seconds, its output in `points`.
double seconds_to_upsample(const InferenceModel& model, int64_t n, int threads,
                           at::Tensor& points) {
    at::set_num_threads(threads);
    UpsampleOptions options;
    options.ratio = 4;
    const auto start = std::chrono::steady_clock::now();
    points = upsample_cloud(*model.backbone, cloud(n), options).points;
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void print_speed_ups() {
    std::printf("speed-up of 2 threads over 1, whole-cloud upsampling at 4x (alternating runs):\n");
    for (const auto& [label, file] : model_files()) {
        const InferenceModel model = load_inference_model(file);
        for (int64_t n : {int64_t(2048), int64_t(200000)}) {
            const int rounds = n <= 2048 ? 5 : 1;
            at::Tensor one, two;
            if (n <= 2048) {  // warm-up
                seconds_to_upsample(model, n, 1, one);
                seconds_to_upsample(model, n, 2, two);
            }
            double t1 = 0, t2 = 0;
            for (int i = 0; i < rounds; ++i) {
                t1 += seconds_to_upsample(model, n, 1, one);
                t2 += seconds_to_upsample(model, n, 2, two);
            }
            std::printf(
                "  %-8s %7lld -> %7lld points: 1 thread %8.3f s, 2 threads %8.3f s: "
                "%.2fx, %s\n",
                label.c_str(), static_cast<long long>(n), static_cast<long long>(4 * n),
                t1 / rounds, t2 / rounds, t1 / t2,
                one.equal(two) ? "same bits" : "DIFFERENT OUTPUTS");
        }
    }
    std::fflush(stdout);
}

void BM_PuGcn(benchmark::State& state) {
    const std::string file = (fs::path(models_dir()) / "pugcn-x4.pt").string();
    if (!fs::exists(file)) {
        state.SkipWithError("no shipped model (models/pugcn-x4.pt)");
        return;
    }
    static const InferenceModel model = load_inference_model(file);
    at::Tensor points;
    for (auto _ : state)
        state.SetIterationTime(
            seconds_to_upsample(model, 2048, static_cast<int>(state.range(0)), points));
}
BENCHMARK(BM_PuGcn)->Arg(1)->Arg(2)->UseManualTime()->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
    pumeta::keep_freed_memory();  // as the CLI runs (core/allocator.h)
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    print_speed_ups();
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
