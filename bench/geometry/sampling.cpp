// Sampling: FPS 8192 -> 2048 points, and 100k uniform / Poisson-disk points on a UV sphere of
// 49,600 triangles. state.range(0) is the number of ATen threads where it matters.
#include "pumeta/geometry/sampling.h"

#include <ATen/ATen.h>
#include <ATen/Parallel.h>
#include <benchmark/benchmark.h>

#include <cmath>
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
BENCHMARK(BM_FarthestPointSampling)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

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

BENCHMARK_MAIN();
