// Sampling: FPS 8192 -> 2048 points, and 100k uniform / Poisson-disk points on a UV sphere of
// 49,600 triangles. state.range(0) is the number of ATen threads where it matters. Before the
// benchmarks, FPS is timed against a plain sequential scan over interleaved xyz (the
// implementation before the per-axis vector lanes) on the same points, the two answers are
// compared, and the ratio printed.
#include "pumeta/geometry/sampling.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

namespace {

using pumeta::uniform_random_points;

/// Unit UV sphere: `rings` latitude bands, `sectors` longitude bands, two pole vertices;
/// 2 * sectors * (rings - 1) triangles.
pumeta::TriangleMesh uv_sphere(int64_t rings, int64_t sectors) {
    const double pi = std::acos(-1.0);
    std::vector<float> vertices{0.f, 0.f, 1.f};
    for (int64_t r = 1; r < rings; ++r)
        for (int64_t s = 0; s < sectors; ++s) {
            const double theta = pi * r / rings, phi = 2 * pi * s / sectors;
            vertices.insert(vertices.end(),
                            {float(std::sin(theta) * std::cos(phi)),
                             float(std::sin(theta) * std::sin(phi)), float(std::cos(theta))});
        }
    vertices.insert(vertices.end(), {0.f, 0.f, -1.f});
    const int64_t south = static_cast<int64_t>(vertices.size() / 3) - 1;
    auto ring_vertex = [sectors](int64_t r, int64_t s) {
        return 1 + (r - 1) * sectors + s % sectors;
    };
    std::vector<int64_t> faces;
    for (int64_t s = 0; s < sectors; ++s) {
        faces.insert(faces.end(), {0, ring_vertex(1, s), ring_vertex(1, s + 1)});
        for (int64_t r = 1; r + 1 < rings; ++r) {
            const int64_t a = ring_vertex(r, s), b = ring_vertex(r, s + 1);
            const int64_t c = ring_vertex(r + 1, s), d = ring_vertex(r + 1, s + 1);
            faces.insert(faces.end(), {a, c, d, a, d, b});
        }
        faces.insert(faces.end(),
                     {south, ring_vertex(rings - 1, s + 1), ring_vertex(rings - 1, s)});
    }
    return {at::tensor(vertices).view({-1, 3}), at::tensor(faces).view({-1, 3})};
}

const pumeta::TriangleMesh& sphere() {
    static const pumeta::TriangleMesh mesh = uv_sphere(125, 200);
    return mesh;
}

void BM_FarthestPointSampling(benchmark::State& state) {
    at::set_num_threads(static_cast<int>(state.range(0)));
    at::Tensor points = uniform_random_points(8192, 1);
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::farthest_point_sampling(points, 2048));
}
/// The baseline: one pass per selected point over interleaved xyz, keeping the first strictly
/// farthest point.
std::vector<int64_t> sequential_fps(const at::Tensor& points, int64_t m) {
    const float* xyz = points.data_ptr<float>();
    const int64_t n = points.size(0);
    std::vector<float> min_sq(n, std::numeric_limits<float>::infinity());
    std::vector<int64_t> out(m);
    int64_t current = 0;
    for (int64_t i = 0; i < m; ++i) {
        out[i] = current;
        const float* c = xyz + 3 * current;
        float best = -1.f;
        for (int64_t j = 0; j < n; ++j) {
            const float dx = xyz[3 * j] - c[0], dy = xyz[3 * j + 1] - c[1],
                        dz = xyz[3 * j + 2] - c[2];
            const float d = dx * dx + dy * dy + dz * dz;
            if (d < min_sq[j]) min_sq[j] = d;
            if (min_sq[j] > best) {
                best = min_sq[j];
                current = j;
            }
        }
    }
    return out;
}

/// Seconds per call of `f`, the best of `repeats` timed calls.
template <typename F>
double best_seconds(int repeats, F&& f) {
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < repeats; ++i) {
        const auto start = std::chrono::steady_clock::now();
        f();
        best = std::min(
            best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    return best;
}

/// Prints the FPS speed-up over the sequential baseline (one thread, 8192 -> 2048 and
/// 4096 -> 1024 points, the sizes of a training step's patches) and whether the answers agree.
void print_fps_against_baseline() {
    at::set_num_threads(1);
    for (const int64_t n : {8192, 4096}) {
        at::Tensor points = uniform_random_points(n, 1);
        const at::Tensor ours = pumeta::farthest_point_sampling(points, n / 4);
        const std::vector<int64_t> baseline = sequential_fps(points, n / 4);
        const bool same = std::equal(baseline.begin(), baseline.end(), ours.data_ptr<int64_t>());
        const double t_base = best_seconds(5, [&] { sequential_fps(points, n / 4); });
        const double t_ours =
            best_seconds(5, [&] { pumeta::farthest_point_sampling(points, n / 4); });
        std::printf(
            "FPS %lld -> %lld, 1 thread: sequential scan %.2f ms, pumeta %.2f ms: %.2fx (%s)\n",
            static_cast<long long>(n), static_cast<long long>(n / 4), 1e3 * t_base, 1e3 * t_ours,
            t_base / t_ours, same ? "same indices" : "INDICES DIFFER");
    }
}

BENCHMARK(BM_FarthestPointSampling)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

/// Prints the pruned FPS against the full scan (farthest_point_sampling on 2 threads, the
/// pruned one on its one) for points on a surface (the UV sphere), picking a quarter: the
/// final selection of an upsampling pass, whose candidates lie on the surfaces.
void print_pruned_fps_against_full_scan() {
    at::set_num_threads(2);
    for (const int64_t n : {8192, 50000, 200000}) {
        at::Tensor points = pumeta::sample_uniform(sphere(), n, 1).points;
        const int repeats = n > 50000 ? 1 : 3;
        at::Tensor full, pruned;
        const double t_full =
            best_seconds(repeats, [&] { full = pumeta::farthest_point_sampling(points, n / 4); });
        const double t_pruned = best_seconds(
            repeats, [&] { pruned = pumeta::farthest_point_sampling_pruned(points, n / 4); });
        std::printf(
            "FPS %lld -> %lld on a sphere: full scan (2 threads) %.1f ms, pruned (1 thread) "
            "%.1f ms: %.1fx (%s)\n",
            static_cast<long long>(n), static_cast<long long>(n / 4), 1e3 * t_full, 1e3 * t_pruned,
            t_full / t_pruned, full.equal(pruned) ? "same indices" : "INDICES DIFFER");
    }
}

void BM_FarthestPointSamplingPruned(benchmark::State& state) {
    at::Tensor points = pumeta::sample_uniform(sphere(), state.range(0), 1).points;
    for (auto _ : state)
        benchmark::DoNotOptimize(
            pumeta::farthest_point_sampling_pruned(points, state.range(0) / 4));
}
BENCHMARK(BM_FarthestPointSamplingPruned)
    ->Arg(8192)
    ->Arg(200000)
    ->Arg(4000000)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

/// Four elements at once, in parallel on two threads.
void BM_FarthestPointSamplingBatched(benchmark::State& state) {
    at::set_num_threads(2);
    at::Tensor points = uniform_random_points(4 * 8192, 1).view({4, 8192, 3});
    for (auto _ : state)
        benchmark::DoNotOptimize(pumeta::farthest_point_sampling_batched(points, 2048));
}
BENCHMARK(BM_FarthestPointSamplingBatched)->Unit(benchmark::kMillisecond)->UseRealTime();

/// The tensor-op path that GPUs take, here on the CPU (float64 input selects it).
void BM_FarthestPointSamplingTensorOps(benchmark::State& state) {
    at::set_num_threads(1);
    at::Tensor points = uniform_random_points(8192, 1).to(at::kDouble).unsqueeze(0);
    for (auto _ : state)
        benchmark::DoNotOptimize(pumeta::farthest_point_sampling_batched(points, 2048));
}
BENCHMARK(BM_FarthestPointSamplingTensorOps)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SampleUniform(benchmark::State& state) {
    sphere();
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::sample_uniform(sphere(), 100000, 1));
}
BENCHMARK(BM_SampleUniform)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PoissonDisk(benchmark::State& state) {
    at::set_num_threads(static_cast<int>(state.range(0)));
    sphere();
    for (auto _ : state) benchmark::DoNotOptimize(pumeta::sample_poisson_disk(sphere(), 100000, 1));
}
BENCHMARK(BM_PoissonDisk)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    print_fps_against_baseline();
    print_pruned_fps_against_full_scan();
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
